# Issue 16 end to end, through the real CLI:
#   sim the calibration flight (arrays as built + GPS log), calibrate from it;
#   sim another scene with the same arrays and errors, and the same scene with ideal arrays;
#   replay it with the site as given (uncalibrated), with the calibrated site, and the ideal one;
#   eval all three and print: ideal / uncalibrated / calibrated DOA medians and track RMSE.
# Every limit in LIMITS ("name<=value", names below) must hold.
string(REPLACE "|" ";" LIMITS "${LIMITS}")
file(REMOVE_RECURSE "${DIR}")
function(run step)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "${step} failed (${code}): ${err}")
  endif()
  set(last_output "${out}" PARENT_SCOPE)
endfunction()
run("sim flight" ${BIN} --log-level warn sim ${SCENARIOS}/calibration-flight.json --out ${DIR}/flight)
run("sim field" ${BIN} --log-level warn sim ${SCENARIOS}/seed002-field-errors.json --out ${DIR}/field)
run("sim ideal" ${BIN} --log-level warn sim ${SCENARIOS}/seed002-ideal-44k.json --out ${DIR}/ideal)
run("calibrate" ${BIN} --log-level warn calibrate ${DIR}/flight/site.json
    --reference ${DIR}/flight/reference.jsonl --out ${DIR}/field/calibrated.json
    --clock-offset-std-s 0.005 --array-position-std-m 0.01)
message("${last_output}")
# The calibrated site names the flight's recordings; the field scene is the same arrays.
file(READ ${DIR}/field/calibrated.json calibrated)
string(REPLACE "../flight/" "" calibrated "${calibrated}")
file(WRITE ${DIR}/field/calibrated.json "${calibrated}")

set(summary "")
foreach(run_name ideal uncalibrated calibrated)
  if(run_name STREQUAL "ideal")
    set(site ${DIR}/ideal/site.json)
    set(truth ${DIR}/ideal/truth.json)
  elseif(run_name STREQUAL "uncalibrated")
    set(site ${DIR}/field/site.json)
    set(truth ${DIR}/field/truth.json)
  else()
    set(site ${DIR}/field/calibrated.json)
    set(truth ${DIR}/field/truth.json)
  endif()
  run("replay ${run_name}" ${BIN} --log-level warn replay ${site}
      --tracks-out ${DIR}/${run_name}.tracks.jsonl --doa-out ${DIR}/${run_name}.doa.jsonl)
  run("eval ${run_name}" ${BIN} eval --truth ${truth} --tracks ${DIR}/${run_name}.tracks.jsonl
      --doa ${DIR}/${run_name}.doa.jsonl --json ${DIR}/${run_name}.eval.json)
  file(READ ${DIR}/${run_name}.eval.json report)
  string(JSON rmse GET "${report}" position rmse_3d_m)
  string(JSON doa0 GET "${report}" doa 0 median_error_deg)
  string(JSON doa1 GET "${report}" doa 1 median_error_deg)
  set(${run_name}_rmse ${rmse})
  set(${run_name}_doa0 ${doa0})
  set(${run_name}_doa1 ${doa1})
  string(APPEND summary "  ${run_name}: DOA median ${doa0} / ${doa1} deg, track RMSE ${rmse} m\n")
endforeach()
message("calibration e2e (seed002 arrays as built, calibrated from a 60 s flight):\n${summary}")

# Ratios to the ideal arrays, the issue's "done when" figures.
foreach(name rmse doa0 doa1)
  execute_process(COMMAND awk "BEGIN { printf \"%.3f\", ${calibrated_${name}} / ${ideal_${name}} }"
                  OUTPUT_VARIABLE ratio_${name})
endforeach()
message("calibrated / ideal: track RMSE x${ratio_rmse}, DOA median x${ratio_doa0} / x${ratio_doa1}")
set(failures "")
foreach(limit IN LISTS LIMITS)
  if(NOT limit MATCHES "^([^<>]+)(<=|>=)(.+)$")
    message(FATAL_ERROR "bad limit: ${limit}")
  endif()
  set(value ${${CMAKE_MATCH_1}})
  execute_process(COMMAND awk "BEGIN { exit !(${value} ${CMAKE_MATCH_2} ${CMAKE_MATCH_3}) }"
                  RESULT_VARIABLE held)
  if(held EQUAL 0)
    message(STATUS "ok   ${limit} (${value})")
  else()
    list(APPEND failures "${limit} (${value})")
  endif()
endforeach()
if(failures)
  message(FATAL_ERROR "limits not met: ${failures}")
endif()
