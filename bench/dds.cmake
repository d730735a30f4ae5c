# DDS end-to-end latency (end of audio frame -> Track at a subscriber) and Doa message rate on
# loopback, plain and with DDS Security; forks the fusion / reader into child processes. Own main:
# prints p50/p99 and rates.
add_executable(dds_latency ${CMAKE_CURRENT_LIST_DIR}/dds_latency.cpp
  ${PROJECT_SOURCE_DIR}/apps/array_node.cpp)
target_include_directories(dds_latency PRIVATE ${PROJECT_SOURCE_DIR})
target_compile_definitions(dds_latency PRIVATE DRONETRACK_VERSION="${PROJECT_VERSION}"
  DRONETRACK_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
target_link_libraries(dds_latency PRIVATE dronetrack_dds_wiring dronetrack_capture
  dronetrack_doa dronetrack_sim dronetrack_options)
set_target_properties(dds_latency PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bench)
