# Array node DSP: bare FFT + cross-spectrum kernel vs the whole NodePipeline, per frame, in one
# run; prints real-time factor per core and the ratio pipeline / kernel.
dronetrack_add_bench(doa_bench SOURCES ${CMAKE_CURRENT_LIST_DIR}/doa_bench.cpp
  LIBS dronetrack_doa PkgConfig::FFTW3)
