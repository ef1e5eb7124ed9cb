// Explicit instantiations of the joint modal filter, float and double, at 3, 10
// and 50 modes (see instantiate_modal.cpp).
#include "fsw/modal/modal_ukf.hpp"

namespace fsw {
template class ModalUkfJoint<double, 3>;
template class ModalUkfJoint<float, 3>;
template class ModalUkfJoint<double, 10>;
template class ModalUkfJoint<float, 10>;
template class ModalUkfJoint<double, 50>;
template class ModalUkfJoint<float, 50>;
}  // namespace fsw
