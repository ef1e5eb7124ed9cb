// The modal estimator's steps (decomposition of an image, bank and joint
// filter steps, shape reconstruction, frequency acquisition: storing images,
// the search, rebuilding an image and the replay) at 50 modes allocate
// nothing: the objects are constructed before the guard, the steps run
// inside it.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "fsw/modal/modal_acquisition.hpp"
#include "fsw/modal/modal_decomposition.hpp"
#include "fsw/modal/modal_shape.hpp"
#include "fsw/modal/modal_ukf.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;

namespace {
constexpr int kM = 50;
constexpr int kN = 300;

template <typename S>
struct Image {
  S phi[kN * kM];
  S z[kN];
  S var[kN];
  Image(double t) {
    for (int k = 0; k < kN; ++k) {
      const double x = (k + 0.5) / kN;
      z[k] = S(0);
      for (int i = 0; i < kM; ++i) {
        phi[k * kM + i] = S(std::sin((i + 1) * M_PI * x));
        z[k] += phi[k * kM + i] * S(std::sin((1 + 0.1 * i) * t) / (i + 1));
      }
      var[k] = S(1e-4);
    }
    z[7] = S(NAN);  // one NaN point on the way
  }
};

template <typename S>
void modal_steps_without_heap() {
  ModalFilterConfig<S, kM> cfg;
  for (int i = 0; i < kM; ++i) cfg.mode[i].omega_radps = S(1 + 0.1 * i);
  // Construction-time allocation is allowed; the steps below must not allocate.
  auto decomp = std::make_unique<ModalDecomposition<S, kM>>();
  auto rec = std::make_unique<ModalDecompositionRecord<S, kM>>();
  auto bank = std::make_unique<ModalUkfBank<S, kM>>(cfg);
  auto joint = std::make_unique<ModalUkfJoint<S, kM>>(cfg);
  auto img0 = std::make_unique<Image<S>>(0.0);
  auto img1 = std::make_unique<Image<S>>(0.5);
  auto shape = std::make_unique<Image<S>>(0.0);
  typename ModalUkfBank<S, kM>::Record rb;
  typename ModalUkfJoint<S, kM>::Record rj;
  Eigen::Matrix<S, kM, 1> a;
  Eigen::Matrix<S, kM, kM> pa;
  S z_out[kN], var_out[kN];
  ShapeRecord sr;
  ModalAcquisitionConfig<S, kM> acfg;
  for (int i = 0; i < kM; ++i) {
    acfg.omega_prior_radps[i] = cfg.mode[i].omega_radps;
    acfg.sigma_omega_radps[i] = S(0.1) * cfg.mode[i].omega_radps;
  }
  auto acq = std::make_unique<ModalAcquisition<S, kM, 256>>(acfg);
  auto rebuilt = std::make_unique<ModalDecompositionRecord<S, kM>>();
  auto replayed = std::make_unique<ModalUkfJoint<S, kM>>(cfg);
  int n_added = 0;

  NoHeapGuard guard;
  for (const Image<S>* img : {img0.get(), img1.get()}) {
    decomp->reset();
    decomp->add_points(img->phi, img->z, img->var, kN);
    ASSERT_EQ(decomp->solve(*rec), ModalStatus::Ok);
    EXPECT_EQ(bank->step(S(0.5), *rec, rb), StepStatus::Ok);
    EXPECT_EQ(joint->step(S(0.5), *rec, rj), StepStatus::Ok);
    for (int r = 0; r < 2; ++r) n_added += acq->add(S(0.5) * S(n_added), *rec) == AcquisitionStatus::Ok;
  }
  const AcquisitionStatus acq_status = acq->search();
  const AcquisitionStatus rebuilt_status = acq->coarse(1, *rebuilt);
  const int replay_fused = acq->replay_into(*replayed, cfg, rj);
  decomp->reset();
  decomp->add_points(img0->phi, img0->z, nullptr, kN);  // eq. 4b path
  EXPECT_EQ(decomp->solve(*rec), ModalStatus::Ok);
  joint->amplitudes(a);
  joint->amplitude_cov(pa);
  sr = reconstruct_shape<S, kM>(a, pa, shape->phi, kN, z_out, var_out);
  EXPECT_EQ(guard.allocations(), 0);
  EXPECT_EQ(sr.status, StepStatus::Ok);
  EXPECT_EQ(n_added, 4);
  EXPECT_EQ(acq_status, AcquisitionStatus::Ok);
  EXPECT_EQ(rebuilt_status, AcquisitionStatus::Ok);
  EXPECT_EQ(replay_fused, 4);
  EXPECT_EQ(rec->n_nonfinite, 1);
  EXPECT_TRUE(std::isfinite(z_out[0]));
}
}  // namespace

TEST(NoHeapModalTest, DecompositionFiltersAndShapeDouble) { modal_steps_without_heap<double>(); }
TEST(NoHeapModalTest, DecompositionFiltersAndShapeFloat) { modal_steps_without_heap<float>(); }
