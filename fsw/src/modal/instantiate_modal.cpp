// Explicit instantiations of the modal estimator for float and double, at the
// sizes of modal_instances.hpp, so a float-only compile error cannot hide;
// everything else links to these. The two filters have their own files
// (the longest compiles in the build, so they run in parallel).
#include "fsw/modal/modal_decomposition.hpp"
#include "fsw/modal/modal_shape.hpp"
#include "fsw/modal/modal_ukf.hpp"

namespace fsw {
#define FSW_DECOMPOSITION(S, M) template class ModalDecomposition<S, M>;
FSW_MODAL_INSTANCES(FSW_DECOMPOSITION)
#undef FSW_DECOMPOSITION
template class ModeUkf<double>;
template class ModeUkf<float>;
template ShapeRecord reconstruct_shape<double, 3>(const Eigen::Matrix<double, 3, 1>&,
                                                  const Eigen::Matrix<double, 3, 3>&, const double*, int, double*,
                                                  double*);
template ShapeRecord reconstruct_shape<float, 3>(const Eigen::Matrix<float, 3, 1>&, const Eigen::Matrix<float, 3, 3>&,
                                                 const float*, int, float*, float*);
template ShapeRecord reconstruct_shape<double, 50>(const Eigen::Matrix<double, 50, 1>&,
                                                   const Eigen::Matrix<double, 50, 50>&, const double*, int, double*,
                                                   double*);
template ShapeRecord reconstruct_shape<float, 50>(const Eigen::Matrix<float, 50, 1>&,
                                                  const Eigen::Matrix<float, 50, 50>&, const float*, int, float*,
                                                  float*);
}  // namespace fsw
