// Boundary validation for the bindings: every array that crosses into the
// flight code is checked for shape and finiteness here, and a failure is a
// ValueError that names the argument. The flight code itself never sees a
// badly shaped or non-finite array from Python.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <cmath>
#include <string>

#include "fsw/math/so3.hpp"

namespace py = pybind11;

namespace bind_detail {

using Arr = py::array_t<double, py::array::c_style | py::array::forcecast>;

inline std::string shape_str(const Arr& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) {
    s += std::to_string(a.shape(i));
    if (i + 1 < a.ndim() || a.ndim() == 1) s += ",";
  }
  return s + ")";
}

// Fixed-size vector from a 1-D array of exactly N finite values.
template <int N>
Eigen::Matrix<double, N, 1> vec(const Arr& a, const char* name) {
  if (a.ndim() != 1 || a.shape(0) != N) {
    throw py::value_error(std::string(name) + ": expected shape (" + std::to_string(N) + ",), got " + shape_str(a));
  }
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) {
    v(i) = a.at(i);
    if (!std::isfinite(v(i))) {
      throw py::value_error(std::string(name) + ": element " + std::to_string(i) + " is not finite (" +
                            std::to_string(v(i)) + ")");
    }
  }
  return v;
}

// Fixed-size matrix from a 2-D array of finite values.
template <int R, int C>
Eigen::Matrix<double, R, C> mat(const Arr& a, const char* name) {
  if (a.ndim() != 2 || a.shape(0) != R || a.shape(1) != C) {
    throw py::value_error(std::string(name) + ": expected shape (" + std::to_string(R) + ", " + std::to_string(C) +
                          "), got " + shape_str(a));
  }
  Eigen::Matrix<double, R, C> m;
  for (int i = 0; i < R; ++i) {
    for (int j = 0; j < C; ++j) {
      m(i, j) = a.at(i, j);
      if (!std::isfinite(m(i, j))) {
        throw py::value_error(std::string(name) + ": element (" + std::to_string(i) + ", " + std::to_string(j) +
                              ") is not finite");
      }
    }
  }
  return m;
}

// Unit quaternion from a scalar-first [w, x, y, z] array.
constexpr double kUnitTol = 1e-6;
inline fsw::Quat<double> quat(const Arr& a, const char* name) {
  const Eigen::Vector4d wxyz = vec<4>(a, name);
  const double norm = wxyz.norm();
  if (std::abs(norm - 1.0) > kUnitTol) {
    throw py::value_error(std::string(name) + ": quaternion [w, x, y, z] must have unit norm, got " +
                          std::to_string(norm));
  }
  return fsw::from_wxyz(wxyz);
}

inline double finite(double x, const char* name) {
  if (!std::isfinite(x)) throw py::value_error(std::string(name) + ": must be finite");
  return x;
}

inline double positive(double x, const char* name) {
  if (!std::isfinite(x) || x <= 0.0) {
    throw py::value_error(std::string(name) + ": must be finite and > 0, got " + std::to_string(x));
  }
  return x;
}

template <typename Derived>
py::array_t<double> to_numpy(const Eigen::MatrixBase<Derived>& m) {
  using Plain = typename Derived::PlainObject;
  const Plain p = m;
  if (Plain::ColsAtCompileTime == 1) {
    py::array_t<double> out(p.rows());
    for (Eigen::Index i = 0; i < p.rows(); ++i) out.mutable_at(i) = p(i);
    return out;
  }
  py::array_t<double> out({p.rows(), p.cols()});
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    for (Eigen::Index j = 0; j < p.cols(); ++j) out.mutable_at(i, j) = p(i, j);
  return out;
}

inline py::array_t<double> quat_to_numpy(const fsw::Quat<double>& q) { return to_numpy(fsw::to_wxyz(q)); }

}  // namespace bind_detail
