// Explicit instantiations of the modal frequency acquisition, float and
// double, at 3, 10 and 50 modes with a 256-image history, and its replay
// into both filters.
#include "fsw/modal/modal_acquisition.hpp"

namespace fsw {
#define FSW_ACQ(S, M)                                                                                        \
  template class ModalAcquisition<S, M, 256>;                                                               \
  template int ModalAcquisition<S, M, 256>::replay_into<ModalUkfJoint<S, M>>(                               \
      ModalUkfJoint<S, M>&, const ModalFilterConfig<S, M>&, ModalUkfJoint<S, M>::Record&);                  \
  template int ModalAcquisition<S, M, 256>::replay_into<ModalUkfBank<S, M>>(                                \
      ModalUkfBank<S, M>&, const ModalFilterConfig<S, M>&, ModalUkfBank<S, M>::Record&);
FSW_ACQ(double, 3)
FSW_ACQ(float, 3)
FSW_ACQ(double, 10)
FSW_ACQ(float, 10)
FSW_ACQ(double, 50)
FSW_ACQ(float, 50)
#undef FSW_ACQ
}  // namespace fsw
