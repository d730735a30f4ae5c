# Issue 19, done when: `record` + `replay` of two arrays recorded with start times 0.5 s apart
# lines them up. The scene is rendered once; `record --from-recording` (the loopback that stands
# in for a device) records A1 whole and A2 from 0.5 s in, stamped 0.5 s later. Replayed, the
# arrays must be lined up: the same track lines as the untrimmed scene's replay from FROM_S on
# on. Not to the last digit: A2's DSP keeps state from its first 0.5 s (noise floors, the TDOA
# regression), so its DOAs stay 0.02-0.07 deg from the untrimmed run's all along, and the track
# within a few centimetres (measured 0.031 m from 5 s, 0.18 m from 3 s); replayed without the
# start times the same recordings put the track 5.5 m off.
set(FROM_S 5)
set(LIMIT_UNITS 1000)  # 0.1 m
include(${CMAKE_CURRENT_LIST_DIR}/run_step.cmake)
fresh_scene()
# Both sites without incident capture: this test is about the alignment only.
file(READ ${DIR}/scene/site.json site)
string(JSON site REMOVE "${site}" incident)
file(WRITE ${DIR}/scene/site-plain.json "${site}")
file(WRITE ${DIR}/site.json "${site}")

run_step("record A1" ${BIN} record --array A1 --from-recording ${DIR}/scene/A1.wav
  --utc-start 2026-11-26T04:00:00Z --out ${DIR}/A1.wav)
run_step("record A2" ${BIN} record --array A2 --from-recording ${DIR}/scene/A2.wav --from-s 0.5
  --utc-start 2026-11-26T04:00:00.500000Z --out ${DIR}/A2.wav)
file(READ ${DIR}/A2.wav.json a2_time)
string(JSON a2_start GET "${a2_time}" utc_start)
string(JSON a2_ns GET "${a2_time}" utc_start_unix_ns)
if(NOT a2_start STREQUAL "2026-11-26T04:00:00.500000Z" OR NOT a2_ns STREQUAL "1795665600500000000")
  message(FATAL_ERROR "A2's sidecar: ${a2_time}")
endif()

run_step("replay of the scene" ${BIN} replay ${DIR}/scene/site-plain.json
  --tracks-out ${DIR}/reference.jsonl)
run_step("replay of the recordings" ${BIN} replay ${DIR}/site.json --tracks-out ${DIR}/aligned.jsonl)
set(err "${STEP_ERR}")
string(REGEX MATCHALL "[^\n]*recordings started[^\n]*" said "${err}")
if(NOT said MATCHES "recordings started 0\\.500000 s apart \\(t = 0 is 2026-11-26T04:00:00\\.000000Z\\): A1 at \\+0\\.000000 s, A2 at \\+0\\.500000 s")
  message(FATAL_ERROR "replay did not say how far apart the recordings started: ${err}")
endif()

# Position of a track line in units of 0.1 mm (the lines print 4 decimals), as "x;y;z".
function(position_units line out)
  string(REGEX MATCH "\"position_m\":\\[([-0-9.]+),([-0-9.]+),([-0-9.]+)\\]" _ "${line}")
  set(values ${CMAKE_MATCH_1} ${CMAKE_MATCH_2} ${CMAKE_MATCH_3})
  set(units "")
  foreach(text IN LISTS values)
    string(REPLACE "." "" value "${text}")
    string(REGEX REPLACE "^(-?)0+([0-9])" "\\1\\2" value "${value}")
    list(APPEND units ${value})
  endforeach()
  set(${out} "${units}" PARENT_SCOPE)
endfunction()
# Largest coordinate difference (0.1 mm) between the confirmed lines of REFERENCE from FROM_S on
# and the lines of the same time and id in CANDIDATE; every one must be there.
function(largest_difference reference candidate out)
  file(STRINGS ${reference} reference_lines)
  file(STRINGS ${candidate} candidate_lines)
  set(largest 0)
  set(compared 0)
  foreach(line IN LISTS reference_lines)
    string(REGEX MATCH "^({\"t\":([0-9]+)\\.[0-9]+,\"id\":[0-9]+,)" _ "${line}")
    set(key "${CMAKE_MATCH_1}")
    if(CMAKE_MATCH_2 LESS FROM_S OR NOT line MATCHES "\"status\":\"confirmed\"")
      continue()
    endif()
    set(match "")
    foreach(other IN LISTS candidate_lines)
      string(FIND "${other}" "${key}" at)
      if(at EQUAL 0)
        set(match "${other}")
        break()
      endif()
    endforeach()
    if(match STREQUAL "")
      message(FATAL_ERROR "${candidate} has no line for ${key}")
    endif()
    position_units("${line}" a)
    position_units("${match}" b)
    foreach(i 0 1 2)
      list(GET a ${i} va)
      list(GET b ${i} vb)
      math(EXPR d "${va} - ${vb}")
      if(d LESS 0)
        math(EXPR d "-${d}")
      endif()
      if(d GREATER largest)
        set(largest ${d})
      endif()
    endforeach()
    math(EXPR compared "${compared} + 1")
  endforeach()
  if(compared LESS 50)
    message(FATAL_ERROR "only ${compared} confirmed track lines compared")
  endif()
  set(${out} ${largest} PARENT_SCOPE)
endfunction()

largest_difference(${DIR}/reference.jsonl ${DIR}/aligned.jsonl aligned_units)
if(aligned_units GREATER LIMIT_UNITS)
  message(FATAL_ERROR "aligned: tracks up to ${aligned_units} x 0.1 mm from the untrimmed replay's "
                      "(limit ${LIMIT_UNITS})")
endif()
# Without the start times (the sidecars gone) the recordings are taken to start together: A2 is
# 0.5 s early and the track is metres off. This is what the alignment removes.
file(MAKE_DIRECTORY ${DIR}/untimed)
file(COPY ${DIR}/A1.wav ${DIR}/A2.wav ${DIR}/site.json DESTINATION ${DIR}/untimed)
run_step("replay without start times" ${BIN} replay ${DIR}/untimed/site.json
  --tracks-out ${DIR}/untimed.jsonl)
if(STEP_ERR MATCHES "recordings started")
  message(FATAL_ERROR "replay without start times lined them up: ${STEP_ERR}")
endif()
largest_difference(${DIR}/reference.jsonl ${DIR}/untimed.jsonl untimed_units)
if(NOT untimed_units GREATER 10000)
  message(FATAL_ERROR "without start times the tracks are only ${untimed_units} x 0.1 mm off: "
                      "the test cannot tell aligned from not")
endif()
message(STATUS "ok: from t ${FROM_S} s the aligned replay's confirmed tracks are within "
               "${aligned_units} x 0.1 mm of the untrimmed replay's (without the start times: "
               "${untimed_units} x 0.1 mm); ${said}")
