# Bare-metal Cortex-M7 (ARMv7E-M, FPv5 double-precision FPU, 16 D registers),
# hard-float ABI, newlib-nano, with Debian's gcc-arm-none-eabi and
# libstdc++-arm-none-eabi-newlib. Used by the firmware build (firmware/):
#   cmake -S . -B build/firmware --toolchain cmake/toolchains/arm-none-eabi-cortex-m7.cmake -DPROXOPS_FIRMWARE=ON
# or `cmake --preset firmware` (CMakePresets.json); `make firmware` does both.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(PROXOPS_ARM_PREFIX arm-none-eabi- CACHE STRING "Cross toolchain prefix")
find_program(CMAKE_C_COMPILER ${PROXOPS_ARM_PREFIX}gcc REQUIRED)
find_program(CMAKE_CXX_COMPILER ${PROXOPS_ARM_PREFIX}g++ REQUIRED)
find_program(CMAKE_OBJDUMP ${PROXOPS_ARM_PREFIX}objdump)
find_program(CMAKE_NM ${PROXOPS_ARM_PREFIX}nm)
find_program(CMAKE_SIZE ${PROXOPS_ARM_PREFIX}size)
set(CMAKE_ASM_COMPILER ${CMAKE_C_COMPILER})

# The compiler checks link a test program; with no board support that needs
# a linker script, so they build a static library instead.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(PROXOPS_CPU_FLAGS "-mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard -mthumb")
set(CMAKE_C_FLAGS_INIT "${PROXOPS_CPU_FLAGS} -ffunction-sections -fdata-sections")
set(CMAKE_CXX_FLAGS_INIT
    "${PROXOPS_CPU_FLAGS} -ffunction-sections -fdata-sections -fno-exceptions -fno-rtti -fno-threadsafe-statics -fno-use-cxa-atexit")
set(CMAKE_ASM_FLAGS_INIT "${PROXOPS_CPU_FLAGS}")
# newlib-nano, no system-call stubs (nosys) and no semihosting library (the
# firmware has its own output path): a dependency on an OS call fails to link.
set(CMAKE_EXE_LINKER_FLAGS_INIT "${PROXOPS_CPU_FLAGS} --specs=nano.specs -Wl,--gc-sections")

# Headers (Eigen) come from the host; libraries and programs only from the toolchain.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
