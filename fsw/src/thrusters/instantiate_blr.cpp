// Explicit instantiations of the thruster learner for both scalar builds, so
// a float-only compile error cannot hide.
#include "fsw/thrusters/blr.hpp"

namespace fsw {
template class BayesLinReg<double, 9, 6, 30>;
template class BayesLinReg<float, 9, 6, 30>;
template class BayesLinReg<double, 37, 6, 30>;
template class BayesLinReg<float, 37, 6, 30>;
template struct ValveFeatures<double, false>;
template struct ValveFeatures<float, false>;
template struct ValveFeatures<double, true>;
template struct ValveFeatures<float, true>;
}  // namespace fsw
