// Explicit instantiations of the relative-motion and attitude propagators: both scalar
// builds, so a float-only compile error cannot hide.
#include "fsw/dynamics/cw.hpp"
#include "fsw/dynamics/hill_attitude.hpp"

namespace fsw {
template class CwPropagator<double>;
template class CwPropagator<float>;
template Mat6<double> cw_stm<double>(double, double);
template Mat6<float> cw_stm<float>(float, float);
template Mat63<double> cw_accel_response<double>(double, double);
template Mat63<float> cw_accel_response<float>(float, float);
template Quat<double> propagate_attitude<double>(const Quat<double>&, const Vec3<double>&, double, double);
template Quat<float> propagate_attitude<float>(const Quat<float>&, const Vec3<float>&, float, float);
}  // namespace fsw
