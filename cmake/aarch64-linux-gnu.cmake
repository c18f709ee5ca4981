# CMake toolchain: cross-compile odonav for arm64 ECUs on a Debian 12 amd64 host with Debian's
# crossbuild-essential-arm64 and the arm64 multiarch -dev packages (scripts/cross-arm64 installs
# them). Tests run under qemu-user (CMAKE_CROSSCOMPILING_EMULATOR): ctest and gtest discovery
# prepend it. fastddsgen and other build tools are the host's.
# The emulator loads the arm64 multiarch glibc (libc6:arm64, /lib/ld-linux-aarch64.so.1), the one
# the -dev packages were installed with, and no -L prefix: the cross sysroot's glibc
# (libc6-arm64-cross, another Debian revision) mixed with the multiarch libc.so.6 that qemu falls
# back to hangs at the first pthread_create.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64)
# GCC contracts a * b + c into one fused multiply-add on aarch64 by default (-ffp-contract=fast),
# which x86-64 without -mfma never does. Off, both round every basic operation alike (IEEE 754).
# The outputs still differ from an amd64 run in their last bits (BENCHMARKS.md, arm64): the two
# glibc libm implementations round some sin, cos and atan2 results differently, and long double is
# 128 bits on aarch64 against 80 on x86-64. -Wno-psabi: GCC's note that the ABI of passing
# std::pair changed in GCC 10 (nothing here is linked against code of an older GCC).
set(CMAKE_C_FLAGS_INIT "-ffp-contract=off")
set(CMAKE_CXX_FLAGS_INIT "-ffp-contract=off -Wno-psabi")
# Libraries and packages: the arm64 ones only; programs: the host's.
set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
# pkg-config: the arm64 .pc files, the arch-independent ones, and an overlay of what cannot be
# installed beside its amd64 twin (ODONAV_CROSS_OVERLAY, see scripts/cross-arm64).
set(_pc /usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig)
if(DEFINED ENV{ODONAV_CROSS_OVERLAY})
  set(_pc "$ENV{ODONAV_CROSS_OVERLAY}/pkgconfig:${_pc}")
endif()
set(ENV{PKG_CONFIG_LIBDIR} "${_pc}")
set(ENV{PKG_CONFIG_PATH} "")
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
