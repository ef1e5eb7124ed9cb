// The self-test firmware: the recorded input (linked into flash) through the
// flight core (selftest.cpp), output over semihosting, exit status the
// self-test's.
//
// Instruction counting under QEMU: the Cortex-M7 cycle counter (DWT) is not
// emulated, so the run uses QEMU's -icount shift=6: every instruction
// advances the virtual clock by exactly 64 ns, and the board's CMSDK timer
// (25 MHz, 40 ns a tick) then reads 1.6 ticks per instruction at any
// instruction (an I/O access ends its translation block, so the time it
// sees is exact). Counts are ticks / 1.6. check_counter() verifies that on
// a loop of known length before the run (the K line).
#include <cstdint>

#include "selftest.hpp"
#include "semihosting.hpp"

// The recorded input, placed in flash by the assembler.
extern "C" const std::uint8_t fw_input_begin[];
extern "C" const std::uint8_t fw_input_end[];
asm(".section .rodata.fw_input,\"a\",%progbits\n"
    ".global fw_input_begin\n"
    ".global fw_input_end\n"
    ".balign 4\n"
    ".type fw_input_begin, %object\n"
    "fw_input_begin:\n"
    ".incbin \"" FW_INPUT_PATH
    "\"\n"
    "fw_input_end:\n"
    ".size fw_input_begin, fw_input_end - fw_input_begin\n"
    ".previous\n");

namespace {

volatile std::uint32_t& reg(std::uint32_t addr) { return *reinterpret_cast<volatile std::uint32_t*>(addr); }

// CMSDK APB timer 0 of the mps2 boards: a 32-bit down counter.
constexpr std::uint32_t kTimer0 = 0x40000000;
constexpr std::uint32_t kCtrl = 0x0, kValue = 0x4, kReload = 0x8;

// Timer ticks per instruction under -icount shift=6 with a 25 MHz timer:
// 64 ns / 40 ns = 8 / 5.
constexpr std::uint32_t kTicksNum = 8, kTicksDen = 5;

std::uint32_t ticks() { return ~reg(kTimer0 + kValue); }

// Instructions since the timer started (exact to +-1; see above).
std::uint32_t instructions() {
  const std::uint64_t t = ticks();
  return static_cast<std::uint32_t>(t * kTicksDen / kTicksNum);
}

void start_timer() {
  reg(kTimer0 + kCtrl) = 0;
  reg(kTimer0 + kReload) = 0xFFFFFFFFu;
  reg(kTimer0 + kValue) = 0xFFFFFFFFu;
  reg(kTimer0 + kCtrl) = 1;  // enable, no interrupt, internal clock
}

// A loop of 2 n + 1 instructions (mov; n x (subs, bne)) measured with the
// counter; its cost without the loop measured the same way is taken off.
std::uint32_t measure_loop(std::uint32_t n) {
  std::uint32_t t0, t1;
  asm volatile(
      "ldr %[t0], [%[v]]\n"
      "mov r3, %[n]\n"
      "1: subs r3, r3, #1\n"
      "bne 1b\n"
      "ldr %[t1], [%[v]]\n"
      : [t0] "=&r"(t0), [t1] "=&r"(t1)
      : [v] "r"(&reg(kTimer0 + kValue)), [n] "r"(n)
      : "r3", "cc", "memory");
  // Down counter; the second load is one instruction after the loop.
  const std::uint64_t dt = static_cast<std::uint64_t>(t0 - t1);
  return static_cast<std::uint32_t>((dt * kTicksDen + kTicksNum / 2) / kTicksNum);
}

class SemihostingOutput final : public fwtest::Output {
 public:
  void write(const char* s, std::size_t n) override { semihosting::write(s, n); }
};

void put_line(const char* tag, std::uint32_t a, std::uint32_t b) {
  char buf[48];
  int k = 0;
  for (const char* p = tag; *p;) buf[k++] = *p++;
  const std::uint32_t values[2] = {a, b};
  for (std::uint32_t v : values) {
    buf[k++] = ' ';
    char tmp[12];
    int m = 0;
    do {
      tmp[m++] = static_cast<char>('0' + v % 10);
      v /= 10;
    } while (v != 0);
    while (m > 0) buf[k++] = tmp[--m];
  }
  buf[k++] = '\n';
  semihosting::write(buf, static_cast<std::size_t>(k));
}

}  // namespace

int main() {
  start_timer();
  // mov + 2 n loop instructions + the closing ldr.
  const std::uint32_t n = 100000;
  put_line("K", 2 * n + 2, measure_loop(n));
  SemihostingOutput out;
  return fwtest::run(fw_input_begin, static_cast<std::size_t>(fw_input_end - fw_input_begin), out, &instructions);
}
