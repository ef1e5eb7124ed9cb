// Reset and fault handling for the Cortex-M7 firmware: the vector table, the
// FPU enabled, .data copied from flash, .bss zeroed, static constructors run,
// then main(). A fault reports itself over semihosting and ends the run.
#include <cstdint>

#include "semihosting.hpp"

extern "C" {
extern std::uint32_t __data_start, __data_end, __data_load, __bss_start, __bss_end, __stack_top;
extern void (*__init_array_start[])();
extern void (*__init_array_end[])();
int main();
[[noreturn]] void Reset_Handler();
[[noreturn]] void Fault_Handler();
}

namespace {
volatile std::uint32_t& reg(std::uint32_t addr) { return *reinterpret_cast<volatile std::uint32_t*>(addr); }
constexpr std::uint32_t kCpacr = 0xE000ED88;  // coprocessor access control
}  // namespace

extern "C" [[noreturn]] void Reset_Handler() {
  reg(kCpacr) |= (0xFu << 20);  // CP10, CP11: full access (the FPU)
  asm volatile("dsb\n isb" ::: "memory");
  const std::uint32_t* src = &__data_load;
  for (std::uint32_t* dst = &__data_start; dst < &__data_end;) *dst++ = *src++;
  for (std::uint32_t* dst = &__bss_start; dst < &__bss_end;) *dst++ = 0;
  for (auto f = __init_array_start; f < __init_array_end; ++f) (*f)();
  semihosting::exit(main());
}

extern "C" [[noreturn]] void* fw_eigen_alloca_forbidden(unsigned) {
  static const char kMsg[] = "E eigen_workspace\n";
  semihosting::write(kMsg, sizeof(kMsg) - 1);
  semihosting::exit(98);
}

extern "C" [[noreturn]] void Fault_Handler() {
  static const char kMsg[] = "E fault\n";
  semihosting::write(kMsg, sizeof(kMsg) - 1);
  semihosting::exit(99);
}

// Initial stack pointer, reset, NMI, HardFault, MemManage, BusFault,
// UsageFault; the rest (SVCall .. external interrupts) are not enabled.
__attribute__((section(".vectors"), used)) const void* const g_vectors[16] = {
    &__stack_top,
    reinterpret_cast<const void*>(&Reset_Handler),
    reinterpret_cast<const void*>(&Fault_Handler),
    reinterpret_cast<const void*>(&Fault_Handler),
    reinterpret_cast<const void*>(&Fault_Handler),
    reinterpret_cast<const void*>(&Fault_Handler),
    reinterpret_cast<const void*>(&Fault_Handler),
    nullptr,
    nullptr,
    nullptr,
    nullptr,
    reinterpret_cast<const void*>(&Fault_Handler),
    reinterpret_cast<const void*>(&Fault_Handler),
    nullptr,
    reinterpret_cast<const void*>(&Fault_Handler),
    reinterpret_cast<const void*>(&Fault_Handler),
};
