// Test tolerances per scalar type. Float tolerances are set by float's
// epsilon (1.2e-7) times the conditioning of each operation; they are the
// documented accuracy of the float build.
#pragma once

template <typename S>
struct Tol;
template <>
struct Tol<double> {
  static constexpr double so3 = 1e-12;    // exp/log/boxplus round trips [rad]
  static constexpr double cw_rel = 1e-9;  // closed form vs integration, relative
};
template <>
struct Tol<float> {
  static constexpr float so3 = 2e-6f;
  static constexpr float cw_rel = 2e-5f;  // float closed form vs double closed form
};
