# Array node DSP: bare FFT + cross-spectrum kernel vs the whole NodePipeline, per frame, in one
# run; prints real-time factor per core and the ratio pipeline / kernel.
dronetrack_add_bench(doa_bench SOURCES ${CMAKE_CURRENT_LIST_DIR}/doa_bench.cpp
  ${CMAKE_CURRENT_LIST_DIR}/fftw_codelets.cpp LIBS dronetrack_doa PkgConfig::FFTW3 ${CMAKE_DL_LIBS})
# fftw_codelets.cpp's fftw_have_simd_avx must be in the dynamic symbol table to take FFTW's calls.
target_link_options(doa_bench PRIVATE -Wl,--export-dynamic-symbol=fftw_have_simd_avx)
