# One step of a CLI test script: runs the command; unless it exits 0 the test fails with the
# exit code and what it printed on stderr. Its stderr is left in STEP_ERR.
function(run_step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code ERROR_VARIABLE err OUTPUT_QUIET)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "${what} exit ${code}: ${err}")
  endif()
  set(STEP_ERR "${err}" PARENT_SCOPE)
endfunction()

# `dronetrack sim SCENARIO --out DIR/scene` into a fresh DIR.
function(fresh_scene)
  file(REMOVE_RECURSE ${DIR})
  file(MAKE_DIRECTORY ${DIR})
  run_step(sim ${BIN} sim ${SCENARIO} --out ${DIR}/scene)
endfunction()
