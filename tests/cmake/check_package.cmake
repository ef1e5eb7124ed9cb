# Installs this build tree into a fresh prefix, then configures, builds and
# runs tests/cmake/consumer against it: find_package(proxops) from outside.
#   cmake -DBUILD=<build tree> -DWORK=<scratch dir> -DSOURCE=<tests/cmake/consumer>
#         [-DGENERATOR=<g> -DMAKE_PROGRAM=<p> -DCXX=<compiler>] -P check_package.cmake
file(REMOVE_RECURSE ${WORK})
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    string(REPLACE ";" " " cmd "${ARGN}")
    message(FATAL_ERROR "failed (${rc}): ${cmd}")
  endif()
endfunction()
run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${WORK}/install)
set(gen)
if(GENERATOR)
  list(APPEND gen -G ${GENERATOR})
endif()
if(MAKE_PROGRAM)
  list(APPEND gen -DCMAKE_MAKE_PROGRAM=${MAKE_PROGRAM})
endif()
run(${CMAKE_COMMAND} -S ${SOURCE} -B ${WORK}/build ${gen} -DCMAKE_CXX_COMPILER=${CXX}
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${WORK}/install)
run(${CMAKE_COMMAND} --build ${WORK}/build)
run(${WORK}/build/consumer)
