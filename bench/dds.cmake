# DDS end-to-end latency (end of audio frame -> Track at a subscriber) and Doa message rate on
# loopback; forks the fusion / reader into child processes. Own main: prints p50/p99 and rates.
add_executable(dds_latency ${CMAKE_CURRENT_LIST_DIR}/dds_latency.cpp
  ${PROJECT_SOURCE_DIR}/apps/array_node.cpp ${PROJECT_SOURCE_DIR}/apps/dds_fusion_service.cpp
  ${PROJECT_SOURCE_DIR}/apps/dds_support.cpp ${PROJECT_SOURCE_DIR}/apps/fusion_driver.cpp
  ${PROJECT_SOURCE_DIR}/apps/track_id_reservation.cpp)
target_include_directories(dds_latency PRIVATE ${PROJECT_SOURCE_DIR})
target_compile_definitions(dds_latency PRIVATE DRONETRACK_VERSION="${PROJECT_VERSION}"
  DRONETRACK_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
target_link_libraries(dds_latency PRIVATE dronetrack_dds dronetrack_config dronetrack_capture
  dronetrack_fusion dronetrack_doa dronetrack_sim dronetrack_common CLI11::CLI11 dronetrack_options)
set_target_properties(dds_latency PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bench)
