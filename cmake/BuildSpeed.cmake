# Build speed (CI time): how our targets are compiled and linked, never what. Included by
# ProjectOptions.cmake; dronetrack_build_speed() runs once at the end of the top-level
# CMakeLists.txt and gives every target of ours (those linking dronetrack_options) its
# precompiled header, so a new library, tool or test needs no line of its own.

# A faster linker: lld (Debian package lld) if the compiler links with it, else the system ld.
# ASan + UBSan link with it too (the sanitizer runtimes are the compiler's, not the linker's).
set(DRONETRACK_LINKER "lld" CACHE STRING "Linker for -fuse-ld= (lld, mold, gold); empty: system ld")
if(DRONETRACK_LINKER)
  include(CheckLinkerFlag)
  check_linker_flag(CXX "-fuse-ld=${DRONETRACK_LINKER}" DRONETRACK_LINKER_WORKS_${DRONETRACK_LINKER})
  if(DRONETRACK_LINKER_WORKS_${DRONETRACK_LINKER})
    target_link_options(dronetrack_options INTERFACE -fuse-ld=${DRONETRACK_LINKER})
    target_link_options(dronetrack_sanitize_only INTERFACE -fuse-ld=${DRONETRACK_LINKER})
  else()
    message(STATUS "dronetrack: -fuse-ld=${DRONETRACK_LINKER} does not link; using the system ld")
  endif()
endif()

# Precompiled headers: the standard headers most files include and Eigen for every target of
# ours (pch/core.hpp), GoogleTest too for the tests (pch/test.hpp). One PCH per kind, built once
# by an object library below and reused (REUSE_FROM) by all targets of that kind, so no
# translation unit parses them again. The reusing targets compile with the same flags
# (dronetrack_options); if one did not, GCC would read the headers as text (-Winvalid-pch, added
# by CMake, says so in the build log) and Clang would stop with an error. Clang (the asan preset,
# with the fuzz harnesses) uses them too since session 25 (its build times with and without
# them: docs/ci.md "The sanitizer build with the PCH and unity batches").
# Off: -DDRONETRACK_PCH=OFF (e.g. to check a file's includes are complete on its own).
option(DRONETRACK_PCH "Precompiled headers for our libraries, executables and tests" ON)

# Unity builds (CI time): a library's or the executable's files compiled in batches, so that the
# template code most of them instantiate alike (Eigen's decompositions in doa/ and fusion/,
# nlohmann-json, and CLI11 2.1, which is header-only and compiles its whole App in every file
# that includes it: ~15 s of CPU per file under ASan) is compiled once per batch, not once per
# file. The arithmetic is unchanged (no -march, so no FMA contraction outside the Highway
# kernels, which are not batched: they include themselves once per vector target). A file
# that must compile alone: set_source_files_properties(... SKIP_UNITY_BUILD_INCLUSION ON).
# Off: -DDRONETRACK_UNITY=OFF (e.g. to check that each file's includes are complete alone).
# Clang batches too, with the PCH on: without it Clang rejected Eigen's out-of-line product
# kernels in a batch that included httplib before Eigen (session 22, not traced); the PCH puts
# Eigen first in every batch, and with it the whole asan preset (tests and fuzz harnesses)
# builds and passes.
option(DRONETRACK_UNITY "Compile our libraries and the executable in batches of files" ON)
set(DRONETRACK_UNITY_BATCH_SIZE 8 CACHE STRING "Files per unity batch")

# The targets of directory `dir` and below.
function(_dronetrack_targets_below dir out)
  get_property(targets DIRECTORY ${dir} PROPERTY BUILDSYSTEM_TARGETS)
  get_property(subdirs DIRECTORY ${dir} PROPERTY SUBDIRECTORIES)
  foreach(sub IN LISTS subdirs)
    _dronetrack_targets_below(${sub} sub_targets)
    list(APPEND targets ${sub_targets})
  endforeach()
  set(${out} ${targets} PARENT_SCOPE)
endfunction()

function(dronetrack_build_speed)
  # Clang's batches need the PCH (above): without it, Clang compiles file by file.
  if(DRONETRACK_UNITY AND (DRONETRACK_PCH OR CMAKE_CXX_COMPILER_ID STREQUAL "GNU"))
    _dronetrack_targets_below(${PROJECT_SOURCE_DIR} unity_targets)
    foreach(target IN LISTS unity_targets)
      get_target_property(type ${target} TYPE)
      get_target_property(links ${target} LINK_LIBRARIES)
      # The tests too: each test file of a target with several keeps its helpers in a namespace
      # named after the file (tests/README.md), so two files' kRate or run() do not meet.
      if(type MATCHES "^(STATIC_LIBRARY|EXECUTABLE)$" AND "dronetrack_options" IN_LIST links)
        set_target_properties(${target} PROPERTIES UNITY_BUILD ON
                              UNITY_BUILD_BATCH_SIZE ${DRONETRACK_UNITY_BATCH_SIZE})
      endif()
    endforeach()
  endif()
  if(NOT DRONETRACK_PCH)
    return()
  endif()
  set(here ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  set(pch_dir ${PROJECT_BINARY_DIR}/pch)
  # A C file too: a target with generated C sources (dronetrack_dds) reuses the (empty) C PCH.
  file(WRITE ${pch_dir}/pch.cpp "// builds the precompiled header\n")
  file(WRITE ${pch_dir}/pch.c "/* the same for C */\n")
  add_library(dronetrack_pch OBJECT ${pch_dir}/pch.cpp ${pch_dir}/pch.c)
  target_link_libraries(dronetrack_pch PRIVATE Eigen3::Eigen dronetrack_options)
  target_precompile_headers(dronetrack_pch PRIVATE ${here}/pch/core.hpp)
  set(test_pch "")
  if(DRONETRACK_BUILD_TESTS)
    find_package(GTest REQUIRED)
    set(test_pch dronetrack_test_pch)
    add_library(dronetrack_test_pch OBJECT ${pch_dir}/pch.cpp ${pch_dir}/pch.c)
    target_link_libraries(dronetrack_test_pch PRIVATE Eigen3::Eigen GTest::gtest dronetrack_options)
    target_precompile_headers(dronetrack_test_pch PRIVATE ${here}/pch/test.hpp)
  endif()
  _dronetrack_targets_below(${PROJECT_SOURCE_DIR} targets)
  foreach(target IN LISTS targets)
    get_target_property(type ${target} TYPE)
    get_target_property(links ${target} LINK_LIBRARIES)
    get_target_property(own_pch ${target} PRECOMPILE_HEADERS)
    if(NOT type MATCHES "^(STATIC_LIBRARY|EXECUTABLE|OBJECT_LIBRARY)$" OR own_pch
       OR NOT "dronetrack_options" IN_LIST links OR target MATCHES "_pch$")
      continue()
    endif()
    # -pthread (PortAudio's pkg-config flags, in dronetrack_capture) defines _REENTRANT, and GCC
    # then refuses the PCH and reads every header of it as text (Clang: an error): such a target
    # goes without.
    set(pthread FALSE)
    foreach(lib IN LISTS links)
      if(TARGET ${lib})
        get_target_property(lib_options ${lib} INTERFACE_COMPILE_OPTIONS)
        if("-pthread" IN_LIST lib_options)
          set(pthread TRUE)
        endif()
      endif()
    endforeach()
    if(pthread)
      continue()
    endif()
    # Eigen's headers come through the PCH: every user gets its include directory.
    target_include_directories(${target} SYSTEM PRIVATE
                               $<TARGET_PROPERTY:Eigen3::Eigen,INTERFACE_INCLUDE_DIRECTORIES>)
    if(test_pch AND ("GTest::gtest_main" IN_LIST links OR "GTest::gtest" IN_LIST links))
      target_precompile_headers(${target} REUSE_FROM ${test_pch})
    else()
      target_precompile_headers(${target} REUSE_FROM dronetrack_pch)
    endif()
  endforeach()
endfunction()
