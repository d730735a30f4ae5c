# Runs BIN with ARGS ("|"-separated); passes when the exit code is EXPECT_CODE and stderr is
# exactly one line.
string(REPLACE "|" ";" ARGS "${ARGS}")
execute_process(COMMAND ${BIN} ${ARGS} RESULT_VARIABLE code ERROR_VARIABLE err OUTPUT_VARIABLE out)
if(NOT code EQUAL EXPECT_CODE)
  message(FATAL_ERROR "exit code ${code}, expected ${EXPECT_CODE}; stderr: ${err}")
endif()
string(STRIP "${err}" err)
string(REGEX MATCHALL "\n" newlines "${err}")
list(LENGTH newlines extra_lines)
if(err STREQUAL "" OR extra_lines GREATER 0)
  message(FATAL_ERROR "expected one error line on stderr, got: [${err}]")
endif()
message(STATUS "ok: ${err}")
