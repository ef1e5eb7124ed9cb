// Explicit instantiations of the dual quaternion helpers and the feature
// filters (the feature paper's 4 points, 4 lines, 2 circles), float and double, so a
// compile error in either scalar build cannot hide.
#include "fsw/dynamics/relative_dynamics.hpp"
#include "fsw/features/feature_filter.hpp"
#include "fsw/features/feature_models.hpp"
#include "fsw/math/dual_quaternion.hpp"

namespace fsw {
template struct DualQuat<double>;
template struct DualQuat<float>;
template DualQuat<double> exp<double>(const Eigen::Matrix<double, 6, 1>&);
template DualQuat<float> exp<float>(const Eigen::Matrix<float, 6, 1>&);
template Eigen::Matrix<double, 6, 1> log<double>(const DualQuat<double>&);
template Eigen::Matrix<float, 6, 1> log<float>(const DualQuat<float>&);
template bool point_model<double>(const DualQuat<double>&, const CameraMount<double>&, const Vec3<double>&,
                                  Vec2<double>&, Mat26<double>*);
template bool point_model<float>(const DualQuat<float>&, const CameraMount<float>&, const Vec3<float>&, Vec2<float>&,
                                 Mat26<float>*);
template bool line_model<double>(const DualQuat<double>&, const CameraMount<double>&, const Vec3<double>&,
                                 const Vec3<double>&, Vec2<double>&, Mat26<double>*);
template bool line_model<float>(const DualQuat<float>&, const CameraMount<float>&, const Vec3<float>&,
                                const Vec3<float>&, Vec2<float>&, Mat26<float>*);
template struct LeaderOrbit<double>;
template struct LeaderOrbit<float>;
template class FeatureFilterBase<double, 4, 4, 2>;
template class FeatureFilterBase<float, 4, 4, 2>;
template class FeatureEkf<double, 4, 4, 2>;
template class FeatureEkf<float, 4, 4, 2>;
template class FeatureUkf<double, 4, 4, 2>;
template class FeatureUkf<float, 4, 4, 2>;
}  // namespace fsw
