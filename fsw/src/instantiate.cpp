// Explicit instantiations: both scalar builds of every template in the core
// are compiled into fsw_core, so a float-only compile error cannot hide.
#include "fsw/cw.hpp"
#include "fsw/hill_attitude.hpp"
#include "fsw/so3.hpp"

namespace fsw {
template class CwPropagator<double>;
template class CwPropagator<float>;
template Mat6<double> cw_stm<double>(double, double);
template Mat6<float> cw_stm<float>(float, float);
template Mat63<double> cw_accel_response<double>(double, double);
template Mat63<float> cw_accel_response<float>(float, float);
template Quat<double> exp<double>(const Vec3<double>&);
template Quat<float> exp<float>(const Vec3<float>&);
template Vec3<double> log<double>(const Quat<double>&);
template Vec3<float> log<float>(const Quat<float>&);
template Quat<double> propagate_attitude<double>(const Quat<double>&, const Vec3<double>&, double, double);
template Quat<float> propagate_attitude<float>(const Quat<float>&, const Vec3<float>&, float, float);
}  // namespace fsw
