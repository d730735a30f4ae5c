# Fusion: filter measurement updates per second (target >= 100,000 UKF updates/s per core) and
# the whole engine's DOA throughput on a four-array scene.
dronetrack_add_bench(fusion_bench SOURCES ${CMAKE_CURRENT_LIST_DIR}/fusion_bench.cpp
  LIBS dronetrack_fusion)
