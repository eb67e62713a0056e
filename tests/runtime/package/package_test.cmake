# ctest -R package: install the runtime, build a game against the installed package, run it.
# Arguments: BUILD_DIR, WORK, GAME_SOURCE, GENERATOR, CXX, BODYBUILDER.
function(step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  message(STATUS "${what}:\n${out}${err}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc})")
  endif()
endfunction()

file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
step("install the runtime" ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK}/prefix --component bb_runtime)
# What a game gets: the library, its headers and the package files; nothing of the offline modules.
file(GLOB_RECURSE installed RELATIVE ${WORK}/prefix ${WORK}/prefix/*)
foreach(f ${installed})
  if(f MATCHES "modeler|mesher|decimate|exporter|motion|OpenMesh|CGAL|openvdb")
    message(FATAL_ERROR "the runtime's install holds ${f}")
  endif()
endforeach()
step("configure the game" ${CMAKE_COMMAND} -S ${GAME_SOURCE} -B ${WORK}/game -G ${GENERATOR}
     -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_PREFIX_PATH=${WORK}/prefix)
step("build the game" ${CMAKE_COMMAND} --build ${WORK}/game)
step("build the built-in body" ${BODYBUILDER} build -o ${WORK}/models)
step("run the game" ${WORK}/game/game ${WORK}/models/default.glb)
