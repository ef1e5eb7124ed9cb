// The firmware's only output path: Arm semihosting (the debugger, or QEMU's
// -semihosting, services a BKPT 0xAB). Outside the flight core, which does
// no I/O; used by the self-test harness to print results and to end the run
// with an exit status. On a flight board this would be the telemetry UART.
#pragma once

#include <cstddef>
#include <cstdint>

namespace semihosting {

// Writes n bytes to the host's standard output.
void write(const char* s, std::size_t n);

// Ends the program; the host process exits with status code.
[[noreturn]] void exit(int code);

}  // namespace semihosting
