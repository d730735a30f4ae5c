# Simulator synthesis speed (issue 3): real-time factor of a 60 s four-array scene.
dronetrack_add_bench(sim_bench SOURCES ${CMAKE_CURRENT_LIST_DIR}/sim_bench.cpp LIBS dronetrack_sim)
target_compile_definitions(sim_bench PRIVATE DRONETRACK_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
