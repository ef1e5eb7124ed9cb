// Eigen settings of the firmware build (included before every source).
//
// Eigen's matrix-matrix kernels (products above 20 in size, triangular
// solves with a matrix right-hand side) take a workspace from their
// blocking object; for fixed-size matrices that is a static buffer inside
// the object, so they never allocate. Their code still holds a fall-back
// for a missing buffer: the heap (std::malloc) by default, or the stack
// (EIGEN_ALLOCA) below EIGEN_STACK_ALLOCATION_LIMIT. Here the fall-back
// goes to fw_eigen_alloca_forbidden(), which ends the run with a fault
// report, and the limit is the whole address space, so the heap branch is
// gone at compile time and the image links no allocator. The self-test
// under QEMU runs every flight step; reaching the fall-back would fail it.
// (The limit also bounds fixed-size objects at compile time; the host
// build keeps Eigen's 128 KB bound, and the stack report bounds the stack.)
#pragma once

#ifdef __cplusplus
extern "C" [[noreturn]] void* fw_eigen_alloca_forbidden(unsigned size);
#define EIGEN_ALLOCA fw_eigen_alloca_forbidden
#define EIGEN_STACK_ALLOCATION_LIMIT 0xFFFFFFFFu
#endif
