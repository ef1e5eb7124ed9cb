// Explicit instantiations of the joint modal filter, float and double, at the
// sizes of modal_instances.hpp (see instantiate_modal.cpp).
#include "fsw/modal/modal_ukf.hpp"

namespace fsw {
#define FSW_JOINT(S, M) template class ModalUkfJoint<S, M>;
FSW_MODAL_INSTANCES(FSW_JOINT)
#undef FSW_JOINT
}  // namespace fsw
