# Installs a build tree of this project into a fresh prefix, then configures,
# builds and runs tests/cmake/consumer against it: find_package(proxops) from
# outside.
#   cmake -DBUILD=<build tree> -DWORK=<scratch dir> -DSOURCE=<tests/cmake/consumer>
#         [-DGENERATOR=<g> -DMAKE_PROGRAM=<p> -DCXX=<compiler>]
#         [-DCORE_SOURCE=<this repository> -DCORE_<VAR>=<value>...] -P check_package.cmake
# With CORE_SOURCE, BUILD is first configured from it with the preset "core"
# (the flight core alone, CMakePresets.json), each CORE_<VAR> given as
# -D<VAR> (CMAKE_BUILD_TYPE, PROXOPS_MARCH, PROXOPS_WERROR,
# PROXOPS_CORE_ASSERTS, CMAKE_CXX_COMPILER_LAUNCHER), and built; the
# install must then hold the core and nothing else (no fsw_vision, no
# fsw_node) and the consumer must find no proxops::fsw_vision.
file(REMOVE_RECURSE ${WORK})
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    string(REPLACE ";" " " cmd "${ARGN}")
    message(FATAL_ERROR "failed (${rc}): ${cmd}")
  endif()
endfunction()
set(gen)
if(GENERATOR)
  list(APPEND gen -G ${GENERATOR})
endif()
if(MAKE_PROGRAM)
  list(APPEND gen -DCMAKE_MAKE_PROGRAM=${MAKE_PROGRAM})
endif()
set(core_only OFF)
if(CORE_SOURCE)
  set(core_only ON)
  file(REMOVE_RECURSE ${BUILD})
  set(core_args)
  foreach(var CMAKE_BUILD_TYPE PROXOPS_MARCH PROXOPS_WERROR PROXOPS_CORE_ASSERTS CMAKE_CXX_COMPILER_LAUNCHER)
    if(DEFINED CORE_${var})
      list(APPEND core_args "-D${var}=${CORE_${var}}")
    endif()
  endforeach()
  execute_process(COMMAND ${CMAKE_COMMAND} --preset core -B ${BUILD} ${gen} -DCMAKE_CXX_COMPILER=${CXX} ${core_args}
                  WORKING_DIRECTORY ${CORE_SOURCE} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): cmake --preset core in ${CORE_SOURCE}")
  endif()
  run(${CMAKE_COMMAND} --build ${BUILD} --parallel 2)
endif()
run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${WORK}/install)
if(core_only)
  file(GLOB_RECURSE extra ${WORK}/install/*fsw_vision* ${WORK}/install/include/fsw_vision/* ${WORK}/install/bin/*)
  if(extra)
    message(FATAL_ERROR "the core-only install holds more than the core: ${extra}")
  endif()
endif()
run(${CMAKE_COMMAND} -S ${SOURCE} -B ${WORK}/build ${gen} -DCMAKE_CXX_COMPILER=${CXX}
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${WORK}/install -DPROXOPS_EXPECT_CORE_ONLY=${core_only})
run(${CMAKE_COMMAND} --build ${WORK}/build)
run(${WORK}/build/consumer)
