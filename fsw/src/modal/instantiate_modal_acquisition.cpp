// Explicit instantiations of the modal frequency acquisition, float and
// double, at the sizes of modal_instances.hpp with a 256-image history, and
// its replay into both filters.
#include "fsw/modal/modal_acquisition.hpp"

namespace fsw {
// S and M are template arguments, where parentheses would not parse.
// NOLINTBEGIN(bugprone-macro-parentheses)
#define FSW_ACQ(S, M)                                                                      \
  template class ModalAcquisition<S, M, 256>;                                              \
  template int ModalAcquisition<S, M, 256>::replay_into<ModalUkfJoint<S, M>>(              \
      ModalUkfJoint<S, M>&, const ModalFilterConfig<S, M>&, ModalUkfJoint<S, M>::Record&); \
  template int ModalAcquisition<S, M, 256>::replay_into<ModalUkfBank<S, M>>(               \
      ModalUkfBank<S, M>&, const ModalFilterConfig<S, M>&, ModalUkfBank<S, M>::Record&);
// NOLINTEND(bugprone-macro-parentheses)
FSW_MODAL_INSTANCES(FSW_ACQ)
#undef FSW_ACQ
}  // namespace fsw
