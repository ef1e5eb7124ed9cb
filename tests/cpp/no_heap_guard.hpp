// Heap detector for the no-heap test builds. Include from exactly one
// translation unit per test executable (it defines global operator new).
#pragma once

#include <atomic>
#include <cstdlib>
#include <new>

#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "no_heap_guard.hpp needs EIGEN_RUNTIME_NO_MALLOC (name the test test_no_heap*.cpp)"
#endif

namespace no_heap_detail {
inline std::atomic<long>& counter() {
  static std::atomic<long> c{0};
  return c;
}
inline std::atomic<bool>& armed() {
  static std::atomic<bool> a{false};
  return a;
}
}  // namespace no_heap_detail

void* operator new(std::size_t n) {
  if (no_heap_detail::armed().load()) no_heap_detail::counter().fetch_add(1);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void* operator new[](std::size_t n) {
  if (no_heap_detail::armed().load()) no_heap_detail::counter().fetch_add(1);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

// While alive: Eigen allocations abort (EIGEN_RUNTIME_NO_MALLOC) and any
// operator new is counted.
class NoHeapGuard {
 public:
  explicit NoHeapGuard(bool eigen_forbid = true) : eigen_forbid_(eigen_forbid) {
    start_ = no_heap_detail::counter().load();
    no_heap_detail::armed().store(true);
    if (eigen_forbid_) Eigen::internal::set_is_malloc_allowed(false);
  }
  ~NoHeapGuard() {
    if (eigen_forbid_) Eigen::internal::set_is_malloc_allowed(true);
    no_heap_detail::armed().store(false);
  }
  long allocations() const { return no_heap_detail::counter().load() - start_; }

 private:
  bool eigen_forbid_;
  long start_ = 0;
};
