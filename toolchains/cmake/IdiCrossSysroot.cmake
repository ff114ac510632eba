# The common part of the cross toolchain files (toolchains/<triplet>.cmake set IDI_CROSS_TRIPLET,
# IDI_CROSS_DEB_ARCH and IDI_CROSS_QEMU, then include this). Points compilers, find_* and pkg-config
# at the sysroot only, so nothing of this machine's amd64 libraries leaks into the target build.
if(NOT IDI_SYSROOT AND DEFINED ENV{IDI_SYSROOT})
  set(IDI_SYSROOT "$ENV{IDI_SYSROOT}")
endif()
if(NOT IDI_SYSROOT)
  message(FATAL_ERROR "Cross build for ${IDI_CROSS_TRIPLET}: set IDI_SYSROOT (cache variable or "
                      "environment) to a sysroot made by tools/sysroot")
endif()
get_filename_component(IDI_SYSROOT "${IDI_SYSROOT}" ABSOLUTE)
if(NOT EXISTS "${IDI_SYSROOT}/usr/include/${IDI_CROSS_TRIPLET}")
  message(FATAL_ERROR "IDI_SYSROOT=${IDI_SYSROOT} is not a ${IDI_CROSS_TRIPLET} sysroot "
                      "(no usr/include/${IDI_CROSS_TRIPLET}); run tools/sysroot")
endif()
set(IDI_SYSROOT "${IDI_SYSROOT}" CACHE PATH "Debian sysroot for ${IDI_CROSS_TRIPLET} (tools/sysroot)")
# try_compile projects re-read this file: hand them the sysroot too.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES IDI_SYSROOT)
set(ENV{IDI_SYSROOT} "${IDI_SYSROOT}")

set(CMAKE_C_COMPILER ${IDI_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${IDI_CROSS_TRIPLET}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${IDI_CROSS_TRIPLET})
set(CMAKE_SYSROOT "${IDI_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${IDI_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
# Without PKG_CONFIG_LIBDIR pkg-config silently answers with this machine's x86_64 libraries.
set(ENV{PKG_CONFIG_DIR} "")
set(ENV{PKG_CONFIG_LIBDIR}
    "${IDI_SYSROOT}/usr/lib/${IDI_CROSS_TRIPLET}/pkgconfig:${IDI_SYSROOT}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${IDI_SYSROOT}")
# Debian's arm64 OpenCV ships OpenCVConfig.cmake only in the heavy libopencv-dev metapackage; a small
# sysroot has the per-module -dev packages, for which toolchains/cmake/opencv-sysroot finds the libs.
if(NOT EXISTS "${IDI_SYSROOT}/usr/lib/${IDI_CROSS_TRIPLET}/cmake/opencv4/OpenCVConfig.cmake")
  set(OpenCV_DIR "${CMAKE_CURRENT_LIST_DIR}/opencv-sysroot" CACHE PATH "OpenCV module finder")
endif()
# ctest runs the cross-built tests through qemu-user with the sysroot's loader and libraries.
find_program(IDI_QEMU_USER ${IDI_CROSS_QEMU})
if(IDI_QEMU_USER)
  set(CMAKE_CROSSCOMPILING_EMULATOR "${IDI_QEMU_USER};-L;${IDI_SYSROOT}")
endif()
# CPack: mark the packages with the target's architecture (else an arm64 binary lands in _amd64.deb).
set(IDI_DEB_ARCHITECTURE ${IDI_CROSS_DEB_ARCH})
