# `dronetrack sim` then `replay` on a site where one array has a fault (issue 16: a mic wired
# inverted, two channels swapped, a channel late): the replay completes (exit 0) and warns exactly
# once with WARNING (the array and the channel), plus the run's one summary line for that array
# holding SUMMARY; no other line names a channel of A1 or A2.
file(REMOVE_RECURSE ${DIR})
file(MAKE_DIRECTORY ${DIR})
execute_process(COMMAND ${BIN} sim ${SCENARIO} --out ${DIR}/scene
  RESULT_VARIABLE code ERROR_VARIABLE err OUTPUT_QUIET)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "sim exit ${code}: ${err}")
endif()
execute_process(COMMAND ${BIN} --log-level warn replay ${DIR}/scene/site.json
  --tracks-out ${DIR}/tracks.jsonl RESULT_VARIABLE code ERROR_VARIABLE err OUTPUT_QUIET)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "replay exit ${code}: ${err}")
endif()
# The lines hold semicolons, which CMake lists split on.
string(REPLACE ";" "," err "${err}")
string(REGEX MATCHALL "[^\n]*A[12] channel [0-9][^\n]*" named "${err}")
string(REPLACE ";" "," SUMMARY "${SUMMARY}")
string(REGEX MATCHALL "[^\n]*warn: ${WARNING}[^\n]*" warned "${err}")
string(REGEX MATCHALL "[^\n]*replay: audio problems: ${SUMMARY}[^\n]*" summed "${err}")
list(LENGTH named named_count)
list(LENGTH warned warned_count)
list(LENGTH summed summed_count)
if(NOT warned_count EQUAL 1 OR NOT summed_count EQUAL 1 OR NOT named_count EQUAL 2)
  message(FATAL_ERROR "expected one warning '${WARNING}' and its summary line '${SUMMARY}', "
                      "nothing else naming a channel; stderr:\n${err}")
endif()
message(STATUS "ok: ${warned}")
