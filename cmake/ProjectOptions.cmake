# Shared compile options as INTERFACE targets, linked by every target of ours (never by
# third-party code, so their warnings stay theirs).
add_library(dronetrack_options INTERFACE)
target_compile_options(dronetrack_options INTERFACE
  $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align
                            -Woverloaded-virtual -Wnull-dereference -Wimplicit-fallthrough>)
# Eigen's vectorised code is worth it on the per-measurement path; stay portable across x86-64
# machines (no -march=native: the binary may move between nodes).
if(DRONETRACK_FUZZ AND NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR "DRONETRACK_FUZZ needs clang (libFuzzer): configure with "
                      "CC=clang CXX=clang++, as scripts/fuzz.sh does")
endif()
# Fuzzing: the same sanitizers, plus libFuzzer's coverage hooks on every object of ours
# (fuzzer-no-link: the harness executables alone link libFuzzer's main, fuzz/CMakeLists.txt).
set(_dronetrack_fuzz_flags "")
if(DRONETRACK_FUZZ)
  set(_dronetrack_fuzz_flags -fsanitize=fuzzer-no-link)
endif()
# The sanitizer build is RelWithDebInfo for its stack traces: line tables (-g1) give the same
# ASan/UBSan traces (file:line, inlined frames included) as full -g, and compile and link faster.
# The asan preset compiles at -O1 (ASan's documented level for reasonable speed) rather than -O2:
# fusion/fusion_engine.cpp alone took 129 s at -O2 and 89 s at -O1 under ASan + UBSan.
if(DRONETRACK_SANITIZE OR DRONETRACK_FUZZ)
  target_compile_options(dronetrack_options INTERFACE ${_dronetrack_fuzz_flags}
    -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
    $<$<CONFIG:RelWithDebInfo>:-g1>)
  target_link_options(dronetrack_options INTERFACE -fsanitize=address,undefined)
  # GCC's manual (Instrumentation Options): "sanitizers tend to increase the rate of false
  # positive warnings, most notably those around -Wmaybe-uninitialized". GCC 12 + ASan printed
  # 56 of them, all inside libstdc++'s <regex> as instantiated by the tests' text checkers; the
  # release build keeps the warning, so a real one in our code is still reported there.
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(dronetrack_options INTERFACE
      $<$<COMPILE_LANGUAGE:CXX>:-Wno-maybe-uninitialized>)
  endif()
endif()

# Generated sources (idlc C files) get the sanitizer but not our warning set.
add_library(dronetrack_sanitize_only INTERFACE)
if(DRONETRACK_SANITIZE OR DRONETRACK_FUZZ)
  target_compile_options(dronetrack_sanitize_only INTERFACE ${_dronetrack_fuzz_flags}
    -fsanitize=address,undefined -fno-omit-frame-pointer $<$<CONFIG:RelWithDebInfo>:-g1>)
  target_link_options(dronetrack_sanitize_only INTERFACE -fsanitize=address,undefined)
endif()

# Linker, precompiled headers: cmake/BuildSpeed.cmake.
include(${CMAKE_CURRENT_LIST_DIR}/BuildSpeed.cmake)
