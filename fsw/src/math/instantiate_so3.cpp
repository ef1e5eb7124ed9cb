// Explicit instantiations of the rotation helpers, float and double, so a
// float-only compile error cannot hide.
#include "fsw/math/so3.hpp"

namespace fsw {
template Quat<double> exp<double>(const Vec3<double>&);
template Quat<float> exp<float>(const Vec3<float>&);
template Vec3<double> log<double>(const Quat<double>&);
template Vec3<float> log<float>(const Quat<float>&);
}  // namespace fsw
