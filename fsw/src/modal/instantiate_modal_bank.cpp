// Explicit instantiations of the bank of per-mode filters, float and double, at 3, 10
// and 50 modes (see instantiate_modal.cpp).
#include "fsw/modal/modal_ukf.hpp"

namespace fsw {
template class ModalUkfBank<double, 3>;
template class ModalUkfBank<float, 3>;
template class ModalUkfBank<double, 10>;
template class ModalUkfBank<float, 10>;
template class ModalUkfBank<double, 50>;
template class ModalUkfBank<float, 50>;
}  // namespace fsw
