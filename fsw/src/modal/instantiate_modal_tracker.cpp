// Explicit instantiations of the on-board modal tracker at the flight
// application's mode count, float and double.
#include "fsw/modal/modal_tracker.hpp"

namespace fsw {
template class ModalTracker<double, 10>;
template class ModalTracker<float, 10>;
}  // namespace fsw
