// Heap detector for the no-heap test builds. Include from exactly one
// translation unit per test executable: it defines the C allocation
// functions.
//
// The flight code under test is compiled once, in fsw_core (explicit
// instantiations), not in the test's own translation unit, so a check that
// lives in headers (Eigen's EIGEN_RUNTIME_NO_MALLOC) would not see it.
// Instead the executable interposes malloc and its siblings (glibc resolves
// every call to them, its own and other libraries' included, to the
// executable's definitions) and counts each one made while a guard is
// armed, then hands it to glibc's allocator. operator new, Eigen's aligned
// allocations and std containers all come through here.
#pragma once

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>

#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "no_heap_guard.hpp needs EIGEN_RUNTIME_NO_MALLOC (name the test test_no_heap*.cpp)"
#endif

namespace no_heap_detail {
// Constant-initialised: safe to touch from malloc before main.
inline std::atomic<long> g_count{0};
inline std::atomic<bool> g_armed{false};
inline void note() {
  if (g_armed.load(std::memory_order_relaxed)) g_count.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace no_heap_detail

#if defined(__SANITIZE_ADDRESS__)
// Under AddressSanitizer (the "asan" build) the sanitizer owns the
// allocator: interposing malloc here would hand it blocks it did not make.
// Its allocation hook counts instead, for every allocation in the process.
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*)(const volatile void*, std::size_t),
                                                         void (*)(const volatile void*));
namespace no_heap_detail {
inline void on_malloc(const volatile void*, std::size_t) { note(); }
inline void on_free(const volatile void*) {}
inline const int g_hooks_installed = __sanitizer_install_malloc_and_free_hooks(on_malloc, on_free);
}  // namespace no_heap_detail
#else
// glibc's allocator under its own names.
extern "C" void* __libc_malloc(std::size_t n);
extern "C" void* __libc_calloc(std::size_t count, std::size_t n);
extern "C" void* __libc_realloc(void* p, std::size_t n);
extern "C" void* __libc_memalign(std::size_t alignment, std::size_t n);

extern "C" void* malloc(std::size_t n) noexcept {
  no_heap_detail::note();
  return __libc_malloc(n);
}
extern "C" void* calloc(std::size_t count, std::size_t n) noexcept {
  no_heap_detail::note();
  return __libc_calloc(count, n);
}
extern "C" void* realloc(void* p, std::size_t n) noexcept {
  no_heap_detail::note();
  return __libc_realloc(p, n);
}
extern "C" void* aligned_alloc(std::size_t alignment, std::size_t n) noexcept {
  no_heap_detail::note();
  return __libc_memalign(alignment, n);
}
extern "C" void* memalign(std::size_t alignment, std::size_t n) noexcept {
  no_heap_detail::note();
  return __libc_memalign(alignment, n);
}
extern "C" int posix_memalign(void** out, std::size_t alignment, std::size_t n) noexcept {
  no_heap_detail::note();
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, n);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
#endif  // __SANITIZE_ADDRESS__

// While alive: every allocation in the process is counted, and Eigen code
// compiled in the test's own translation unit aborts on allocation
// (EIGEN_RUNTIME_NO_MALLOC), which names the expression that allocated.
class NoHeapGuard {
 public:
  explicit NoHeapGuard(bool eigen_forbid = true) : eigen_forbid_(eigen_forbid) {
#if defined(__SANITIZE_ADDRESS__)
    (void)no_heap_detail::g_hooks_installed;  // odr-used: the hooks are installed at start-up
#endif
    start_ = no_heap_detail::g_count.load();
    no_heap_detail::g_armed.store(true);
    if (eigen_forbid_) Eigen::internal::set_is_malloc_allowed(false);
  }
  ~NoHeapGuard() {
    if (eigen_forbid_) Eigen::internal::set_is_malloc_allowed(true);
    no_heap_detail::g_armed.store(false);
  }
  NoHeapGuard(const NoHeapGuard&) = delete;
  NoHeapGuard& operator=(const NoHeapGuard&) = delete;
  long allocations() const { return no_heap_detail::g_count.load() - start_; }

 private:
  bool eigen_forbid_;
  long start_ = 0;
};
