# Cross-build for arm64 (issue 21) with Debian's cross compiler (g++-aarch64-linux-gnu) and the
# arm64 libraries of a multiarch install (`dpkg --add-architecture arm64`), which live beside the
# host's under /usr: no sysroot. scripts/arm64-test.sh installs both and runs the tests.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
# GCC's arm64 notes that passing std::pair by value changed ABI in GCC 10 concern objects built
# by older compilers, which nothing here links.
set(CMAKE_CXX_FLAGS_INIT "-Wno-psabi")
# find_package looks in /usr/lib/aarch64-linux-gnu/cmake, never in the host's triplet folder.
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
# pkg-config reads the arm64 .pc files (and the architecture-independent ones: eigen3), not the
# host's, which would link x86-64 libraries.
set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig")
# ctest and gtest_discover_tests run the arm64 binaries through qemu-user; the arm64 loader and
# libraries come from the multiarch install, so qemu needs no -L.
find_program(DRONETRACK_QEMU_AARCH64 qemu-aarch64 qemu-aarch64-static)
if(DRONETRACK_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${DRONETRACK_QEMU_AARCH64})
endif()
