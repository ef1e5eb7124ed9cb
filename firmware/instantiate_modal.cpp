// The modal estimator at the flight application's mode count, float: the
// longest compile of the firmware, in its own translation unit so that it
// builds beside selftest.cpp (which declares these extern).
#include "fsw/modal_tracker.hpp"

namespace fsw {
template class ModalDecomposition<float, 10>;
template class ModalUkfJoint<float, 10>;
template class ModalAcquisition<float, 10, 256>;
template class ModalTracker<float, 10>;
}  // namespace fsw
