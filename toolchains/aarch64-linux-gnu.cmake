# Cross-compiling for 64-bit ARM Linux (Debian's aarch64-linux-gnu-gcc 12) against a Debian 12 arm64
# sysroot that tools/sysroot builds. The sysroot is passed in, never hard-coded:
#   cmake --preset cross-arm64-rmp                      (uses build/sysroot/bookworm-arm64-rmp)
#   cmake -B build/x -DCMAKE_TOOLCHAIN_FILE=toolchains/aarch64-linux-gnu.cmake -DIDI_SYSROOT=/path
# or the environment variable IDI_SYSROOT. Tests run under qemu-user (package qemu-user) through
# CMAKE_CROSSCOMPILING_EMULATOR, so ctest works on an amd64 machine.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(IDI_CROSS_TRIPLET aarch64-linux-gnu)
set(IDI_CROSS_DEB_ARCH arm64)
set(IDI_CROSS_QEMU qemu-aarch64)
include(${CMAKE_CURRENT_LIST_DIR}/cmake/IdiCrossSysroot.cmake)
# GCC notes on aarch64 that std::pair<double, double> is passed differently since GCC 10.1 (a psABI
# change). Everything here is built by one compiler, so the note only hides real warnings.
string(APPEND CMAKE_CXX_FLAGS_INIT " -Wno-psabi")
