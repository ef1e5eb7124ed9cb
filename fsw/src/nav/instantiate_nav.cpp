// Explicit instantiations of the navigation filter: float and double, 9 and
// 15 states, so a compile error in any combination cannot hide.
#include "fsw/math/covariance.hpp"
#include "fsw/nav/nav_state.hpp"
#include "fsw/nav/nav_ukf.hpp"

namespace fsw {
template struct NavState<double, false>;
template struct NavState<float, false>;
template struct NavState<double, true>;
template struct NavState<float, true>;
template class NavUkf<double, false>;
template class NavUkf<float, false>;
template class NavUkf<double, true>;
template class NavUkf<float, true>;
}  // namespace fsw
