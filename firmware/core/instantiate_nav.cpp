// The firmware's flight core, float only: the navigation UKF (9 states) and
// the CW propagator it uses.
#include "fsw/dynamics/cw.hpp"
#include "fsw/nav/nav_state.hpp"
#include "fsw/nav/nav_ukf.hpp"

namespace fsw {
template class CwPropagator<float>;
template struct NavState<float, false>;
template class NavUkf<float, false>;
}  // namespace fsw
