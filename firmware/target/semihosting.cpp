#include "semihosting.hpp"

namespace semihosting {
namespace {

constexpr std::uint32_t kSysOpen = 0x01;
constexpr std::uint32_t kSysWrite = 0x05;
constexpr std::uint32_t kSysExitExtended = 0x20;
constexpr std::uint32_t kAdpStoppedApplicationExit = 0x20026;

std::uint32_t call(std::uint32_t op, const void* args) {
  register std::uint32_t r0 asm("r0") = op;
  register const void* r1 asm("r1") = args;
  asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
  return r0;
}

int stdout_handle() {
  static int handle = -1;
  if (handle < 0) {
    // ":tt" opened for writing ("w", mode 4) is the host's standard output.
    static const char kName[] = ":tt";
    const std::uint32_t args[3] = {reinterpret_cast<std::uint32_t>(kName), 4u, 3u};
    handle = static_cast<int>(call(kSysOpen, args));
  }
  return handle;
}

}  // namespace

void write(const char* s, std::size_t n) {
  const std::uint32_t args[3] = {static_cast<std::uint32_t>(stdout_handle()), reinterpret_cast<std::uint32_t>(s),
                                 static_cast<std::uint32_t>(n)};
  call(kSysWrite, args);
}

void exit(int code) {
  const std::uint32_t args[2] = {kAdpStoppedApplicationExit, static_cast<std::uint32_t>(code)};
  for (;;) call(kSysExitExtended, args);
}

}  // namespace semihosting
