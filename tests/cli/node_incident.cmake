# Issue 19: incident capture at `dronetrack node`. A fusion and two nodes replaying the incident
# scene in real time over DDS (loopback, domain DOMAIN): the fusion publishes the zone alert, each
# node takes it from the Alert topic and saves its own array's clip (named with the array), with
# its time sidecar, its DOA lines and the alert; both clips start at the same instant.
include(${CMAKE_CURRENT_LIST_DIR}/run_step.cmake)
fresh_scene()
set(ENV{CYCLONEDDS_URI} "file://${CYCLONE_XML}")
string(TIMESTAMP now "%s" UTC)
math(EXPR epoch "${now} + 3")  # time for discovery before the nodes' first block is due
# One pipeline runs the three processes at once; they read no stdin.
execute_process(
  COMMAND ${BIN} fusion ${DIR}/scene/site.json --domain ${DOMAIN} --duration 16
          --tracks-out ${DIR}/fusion.jsonl
  COMMAND ${BIN} node ${DIR}/scene/site.json --array A1 --realtime --epoch ${epoch} --domain ${DOMAIN}
  COMMAND ${BIN} node ${DIR}/scene/site.json --array A2 --realtime --epoch ${epoch} --domain ${DOMAIN}
  RESULTS_VARIABLE codes ERROR_VARIABLE err OUTPUT_QUIET)
if(NOT codes STREQUAL "0;0;0")
  message(FATAL_ERROR "fusion, node A1, node A2 exit ${codes}: ${err}")
endif()
foreach(array A1 A2)
  file(GLOB clip LIST_DIRECTORIES true ${DIR}/scene/incidents/*-yard-track*-${array})
  list(LENGTH clip count)
  if(NOT count EQUAL 1)
    message(FATAL_ERROR "node ${array}: ${count} clips (${clip}): ${err}")
  endif()
  foreach(file ${array}.wav ${array}.wav.json doa.jsonl alert.json)
    if(NOT EXISTS ${clip}/${file})
      message(FATAL_ERROR "${clip}: no ${file}")
    endif()
  endforeach()
  file(STRINGS ${clip}/doa.jsonl doas)
  list(LENGTH doas doa_count)
  if(doa_count LESS 50 OR NOT doas MATCHES "\"array\":\"${array}\"" OR
     (array STREQUAL "A1" AND doas MATCHES "\"array\":\"A2\""))
    message(FATAL_ERROR "${clip}/doa.jsonl: ${doa_count} lines, not only ${array}'s")
  endif()
  file(READ ${clip}/${array}.wav.json time_${array})
  string(JSON start_${array} GET "${time_${array}}" utc_start_unix_ns)
  string(JSON first_${array} GET "${time_${array}}" first_sample)
endforeach()
if(NOT start_A1 STREQUAL start_A2 OR NOT first_A1 STREQUAL first_A2)
  message(FATAL_ERROR "the nodes' clips start apart: ${time_A1} ${time_A2}")
endif()
message(STATUS "ok: each node saved its clip of the alert (start ${start_A1} ns, sample ${first_A1})")
