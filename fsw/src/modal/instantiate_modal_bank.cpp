// Explicit instantiations of the bank of per-mode filters, float and double, at the
// sizes of modal_instances.hpp (see instantiate_modal.cpp).
#include "fsw/modal/modal_ukf.hpp"

namespace fsw {
#define FSW_BANK(S, M) template class ModalUkfBank<S, M>;
FSW_MODAL_INSTANCES(FSW_BANK)
#undef FSW_BANK
}  // namespace fsw
