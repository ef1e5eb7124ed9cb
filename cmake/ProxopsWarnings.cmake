# proxops_warnings(<target> [PEDANTIC]): the project's warning flags on one
# target, errors when PROXOPS_WERROR is on (CI). Every target this project
# compiles calls it.
function(proxops_warnings target)
  cmake_parse_arguments(ARG "PEDANTIC" "" "" ${ARGN})
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  if(ARG_PEDANTIC)
    target_compile_options(${target} PRIVATE -Wpedantic)
  endif()
  if(PROXOPS_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# proxops_asserts(<target>): compiles <target> with assertions on (NDEBUG
# undefined, so Eigen's index and size checks run) whatever the build type.
function(proxops_asserts target)
  target_compile_options(${target} PRIVATE -UNDEBUG)
endfunction()
