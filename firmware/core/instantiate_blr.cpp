// The firmware's flight core, float only: the thruster learner (valve
// features without pairs, window 30), as the flight application runs it.
#include "fsw/thrusters/blr.hpp"

namespace fsw {
template class BayesLinReg<float, 9, 6, 30>;
template struct ValveFeatures<float, false>;
}  // namespace fsw
