// The flight navigation configuration in a filter's scalar: the Python
// NavConfig is the double one; a float filter takes its fields rounded to
// float (time fields stay double in both builds).
#pragma once

#include "fsw/nav/nav_ukf.hpp"

namespace bind_detail {

template <typename S>
fsw::NavConfig<S> nav_config_as(const fsw::NavConfig<double>& c) {
  fsw::NavConfig<S> o;
  o.n_radps = S(c.n_radps);
  o.dt_imu_s = c.dt_imu_s;
  o.accel_sigma_mps2 = S(c.accel_sigma_mps2);
  o.gyro_sigma_rps = S(c.gyro_sigma_rps);
  o.gap_accel_sigma_mps2 = S(c.gap_accel_sigma_mps2);
  o.gap_gyro_sigma_rps = S(c.gap_gyro_sigma_rps);
  o.gyro_bias_walk = S(c.gyro_bias_walk);
  o.accel_bias_walk = S(c.accel_bias_walk);
  o.gate_chi2 = S(c.gate_chi2);
  o.max_delay_s = c.max_delay_s;
  o.time_tol_s = c.time_tol_s;
  o.max_dt_s = c.max_dt_s;
  o.max_gap_s = c.max_gap_s;
  o.alpha = S(c.alpha);
  o.beta = S(c.beta);
  o.kappa = S(c.kappa);
  o.var_min = S(c.var_min);
  o.pos_var_max_m2 = S(c.pos_var_max_m2);
  o.vel_var_max_m2ps2 = S(c.vel_var_max_m2ps2);
  o.att_var_max_rad2 = S(c.att_var_max_rad2);
  o.gyro_bias_var_max = S(c.gyro_bias_var_max);
  o.accel_bias_var_max = S(c.accel_bias_var_max);
  o.quat_unit_tol = S(c.quat_unit_tol);
  return o;
}

}  // namespace bind_detail
