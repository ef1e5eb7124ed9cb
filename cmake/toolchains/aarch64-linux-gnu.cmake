# aarch64 Linux (Debian's g++-aarch64-linux-gnu), for the flight core's
# GoogleTest suite run under qemu-aarch64 (user mode, Debian's qemu-user):
#   cmake --preset aarch64 && cmake --build --preset aarch64 && ctest --preset aarch64
# (`make test-aarch64`; docs/FIRMWARE.md). GoogleTest is built from the
# sources Debian installs with libgtest-dev (/usr/src/googletest); Eigen's
# headers come from the host.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)

set(PROXOPS_AARCH64_PREFIX aarch64-linux-gnu- CACHE STRING "Cross toolchain prefix")
find_program(CMAKE_C_COMPILER ${PROXOPS_AARCH64_PREFIX}gcc REQUIRED)
find_program(CMAKE_CXX_COMPILER ${PROXOPS_AARCH64_PREFIX}g++ REQUIRED)

set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)

# Test programs (and GoogleTest's test discovery) run through the emulator.
find_program(PROXOPS_QEMU_AARCH64 qemu-aarch64 REQUIRED)
set(CMAKE_CROSSCOMPILING_EMULATOR ${PROXOPS_QEMU_AARCH64} -L /usr/aarch64-linux-gnu)
