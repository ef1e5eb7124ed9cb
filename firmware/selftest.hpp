// The firmware self-test: recorded link input through the flight core, its
// output as text lines. The same source runs on the target (under QEMU,
// output by semihosting) and on the host (linked to the host float build),
// so the two outputs can be compared line by line (tests/py/test_firmware.py).
//
// Input: link frames (COBS, each ending in 0x00) as the ground sends them:
// IMU samples, LED poses, thruster valve intervals, range-image segments and
// the commands that reset and configure the flight software.
//
// Output lines (one space between fields; numbers in decimal, bytes in hex):
//   F <frame index> <apid> <instructions>   a frame into FlightApp<float>::on_bytes
//   T <hex>                                  the telemetry frames it produced
//   A <counter name> <value>                 the application's counters at the end
//   C <step> <instructions>                  one call of a flight component
//   K <expected> <measured>                  the instruction counter's check
//   E <status>                               end (0 = every step ran as expected)
// Instruction counts are -1 where there is no counter (the host).
#pragma once

#include <cstddef>
#include <cstdint>

namespace fwtest {

// Where the lines go.
class Output {
 public:
  virtual void write(const char* s, std::size_t n) = 0;

 protected:
  ~Output() = default;
};

// Instruction counter: a count that increases by one per executed
// instruction, or nullptr when there is none.
using Counter = std::uint32_t (*)();

// Runs the recorded input through the flight application, then through the
// components one call at a time. Returns the status written on the E line.
int run(const std::uint8_t* input, std::size_t n, Output& out, Counter counter);

}  // namespace fwtest
