// The firmware's flight core, float only: the modal estimator at the flight
// application's mode count. (The host's fsw/src/*/instantiate_*.cpp compile
// float and double at every mode count; the firmware needs this one.)
#include "fsw/modal/modal_tracker.hpp"

namespace fsw {
template class ModalDecomposition<float, 10>;
template class ModalUkfJoint<float, 10>;
template class ModalAcquisition<float, 10, 256>;
template class ModalTracker<float, 10>;
}  // namespace fsw
