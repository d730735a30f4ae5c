# Simulator synthesis speed (issue 3): real-time factor of a 60 s four-array scene.
dronetrack_add_bench(sim_bench SOURCES ${CMAKE_CURRENT_LIST_DIR}/sim_bench.cpp LIBS dronetrack_sim)
target_compile_definitions(sim_bench PRIVATE DRONETRACK_SOURCE_DIR="${PROJECT_SOURCE_DIR}")

# Seed 001's experiment, PF against EKF under alpha-stable noise (issue 17): a plain program
# printing the paper's table beside ours (not a Google Benchmark: it measures error, not time).
add_executable(seed001_replica ${CMAKE_CURRENT_LIST_DIR}/seed001_replica.cpp)
target_include_directories(seed001_replica PRIVATE ${PROJECT_SOURCE_DIR})
target_link_libraries(seed001_replica PRIVATE dronetrack_sim dronetrack_options)
set_target_properties(seed001_replica PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bench)
