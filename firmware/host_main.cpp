// The self-test on the host, linked to the host build's float flight core:
// the reference the firmware's output under QEMU is compared with.
//   fw_selftest_host <recorded input>  > out.txt
#include <cstdio>
#include <vector>

#include "selftest.hpp"

namespace {
class StdoutOutput final : public fwtest::Output {
 public:
  void write(const char* s, std::size_t n) override { std::fwrite(s, 1, n, stdout); }
};
}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <recorded input>\n", argv[0]);
    return 2;
  }
  std::FILE* f = std::fopen(argv[1], "rb");
  if (f == nullptr) {
    std::perror(argv[1]);
    return 2;
  }
  std::vector<unsigned char> in;
  unsigned char buf[65536];
  std::size_t k;
  while ((k = std::fread(buf, 1, sizeof(buf), f)) > 0) in.insert(in.end(), buf, buf + k);
  std::fclose(f);
  StdoutOutput out;
  return fwtest::run(in.data(), in.size(), out, nullptr);
}
