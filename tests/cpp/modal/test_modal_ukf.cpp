// Modal UKFs (eqs. 5-7) and shape reconstruction (eqs. 8-9): the process
// model against the closed-form decaying sinusoid, convergence of both
// filters on seeded synthetic coarse measurements, the joint filter with one
// mode against the bank, and the off-nominal statuses.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>

#include "fsw/modal/modal_shape.hpp"
#include "fsw/modal/modal_ukf.hpp"

using namespace fsw;

template <typename S>
class ModalUkfTest : public ::testing::Test {};
using Scalars = ::testing::Types<double, float>;
TYPED_TEST_SUITE(ModalUkfTest, Scalars);

namespace {
template <typename S>
struct UkfTol;
template <>
struct UkfTol<double> {
  static constexpr double prop = 1e-10;
};
template <>
struct UkfTol<float> {
  static constexpr double prop = 2e-4;
};

// Two modes with the pendulum's frequencies and damping.
constexpr double kW[2] = {4.31, 8.68};
constexpr double kAl[2] = {0.049, 0.143};
constexpr double kPh[2] = {0.4, 2.0};
constexpr double kDt = 1.0 / 15.0;

double truth(int i, double t) { return std::exp(-kAl[i] * t) * std::sin(kW[i] * t + kPh[i]); }

template <typename S, int M>
ModalFilterConfig<S, M> pendulum_config() {
  ModalFilterConfig<S, M> cfg;
  for (int i = 0; i < M; ++i) {
    cfg.mode[i].omega_radps = S(kW[i % 2] * 1.08);  // 8 % a priori error
    cfg.mode[i].alpha_ps = S(0.1);
    cfg.mode[i].sigma_v0_ps = S(kW[i % 2]);
    cfg.mode[i].sigma_omega0_radps = S(0.1 * kW[i % 2]);
    cfg.mode[i].sigma_alpha0_ps = S(0.1);
    cfg.mode[i].q_a = S(1e-8);
    cfg.mode[i].q_v = S(1e-6);
  }
  return cfg;
}

// Coarse measurements of the two modes with correlated noise of 1-sigma 0.02.
template <typename S>
ModalDecompositionRecord<S, 2> coarse(double t, std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  ModalDecompositionRecord<S, 2> r;
  r.status = ModalStatus::Ok;
  const double s = 0.02, rho = 0.5;
  r.cov_a << S(s * s), S(rho * s * s), S(rho * s * s), S(s * s);
  const double e0 = g(rng), e1 = rho * e0 + std::sqrt(1 - rho * rho) * g(rng);
  r.a_coarse << S(truth(0, t) + s * e0), S(truth(1, t) + s * e1);
  return r;
}

template <typename Filter>
void run_pendulum(Filter& f, unsigned seed, int steps) {
  using S = typename Filter::VecM::Scalar;
  std::mt19937 rng(seed);
  typename Filter::Record rec;
  for (int k = 0; k < steps; ++k) {
    const auto m = coarse<S>(k * kDt, rng);
    ASSERT_EQ(f.step(S(kDt), m, rec), StepStatus::Ok) << "step " << k;
  }
}
}  // namespace

TYPED_TEST(ModalUkfTest, ProcessModelMatchesDecayingSinusoid) {
  using S = TypeParam;
  // A = e^{-al t} sin(w t + ph), V = dA/dt; 100 steps of eq. 5 vs the closed form.
  const double w = 2.3, al = 0.15, ph = 0.7, dt = 0.05;
  S x[4] = {S(std::sin(ph)), S(w * std::cos(ph) - al * std::sin(ph)), S(w), S(al)};
  for (int k = 1; k <= 100; ++k) {
    modal_detail::propagate_mode(x, x, S(dt));
    const double t = k * dt;
    const double a = std::exp(-al * t) * std::sin(w * t + ph);
    const double v = std::exp(-al * t) * (w * std::cos(w * t + ph) - al * std::sin(w * t + ph));
    ASSERT_NEAR(double(x[0]), a, UkfTol<S>::prop) << k;
    ASSERT_NEAR(double(x[1]), v, UkfTol<S>::prop * w) << k;
  }
}

TYPED_TEST(ModalUkfTest, ProcessModelFiniteAtZeroFrequency) {
  using S = TypeParam;
  // w = 0, al = 0: A moves linearly at rate V (the sinc form has no 1/w).
  S x[4] = {S(1), S(0.5), S(0), S(0)};
  modal_detail::propagate_mode(x, x, S(2));
  EXPECT_NEAR(double(x[0]), 2.0, 1e-6);
  EXPECT_NEAR(double(x[1]), 0.5, 1e-6);
}

TYPED_TEST(ModalUkfTest, BankConvergesToTrueFrequencyAndDamping) {
  using S = TypeParam;
  ModalUkfBank<S, 2> bank(pendulum_config<S, 2>());
  run_pendulum(bank, 11, 150);  // 10 s at 15 Hz
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(double(bank.mode_state(i)(2)), kW[i], 0.01 * kW[i]) << "mode " << i;
    EXPECT_NEAR(double(bank.mode_state(i)(3)), kAl[i], 0.03) << "mode " << i;
  }
}

TYPED_TEST(ModalUkfTest, JointConvergesToTrueFrequencyAndDamping) {
  using S = TypeParam;
  auto joint = std::make_unique<ModalUkfJoint<S, 2>>(pendulum_config<S, 2>());
  run_pendulum(*joint, 11, 150);
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(double(joint->mode_state(i)(2)), kW[i], 0.01 * kW[i]) << "mode " << i;
    EXPECT_NEAR(double(joint->mode_state(i)(3)), kAl[i], 0.03) << "mode " << i;
  }
}

// reset(cfg) in place is a fresh filter: a used filter reset to another
// configuration then steps exactly as one constructed with it.
template <typename Filter>
void reset_equals_fresh() {
  using S = typename Filter::VecM::Scalar;
  auto other = pendulum_config<S, 2>();
  for (int i = 0; i < 2; ++i) other.mode[i].omega_radps *= S(0.95);
  auto used = std::make_unique<Filter>(pendulum_config<S, 2>());
  run_pendulum(*used, 5, 40);
  used->reset(other);
  EXPECT_FALSE(used->initialized());
  auto fresh = std::make_unique<Filter>(other);
  run_pendulum(*used, 9, 60);
  run_pendulum(*fresh, 9, 60);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(used->mode_state(i), fresh->mode_state(i)) << "mode " << i;
    EXPECT_EQ(used->mode_cov(i), fresh->mode_cov(i)) << "mode " << i;
  }
}

TYPED_TEST(ModalUkfTest, BankResetEqualsAFreshBank) { reset_equals_fresh<ModalUkfBank<TypeParam, 2>>(); }
TYPED_TEST(ModalUkfTest, JointResetEqualsAFreshJoint) { reset_equals_fresh<ModalUkfJoint<TypeParam, 2>>(); }

TYPED_TEST(ModalUkfTest, JointWithOneModeEqualsBank) {
  using S = TypeParam;
  // Same 4-state UT and the same scalar update: the two filters coincide.
  const auto cfg = pendulum_config<S, 1>();
  ModalUkfBank<S, 1> bank(cfg);
  ModalUkfJoint<S, 1> joint(cfg);
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 0.02);
  typename ModalUkfBank<S, 1>::Record rb;
  typename ModalUkfJoint<S, 1>::Record rj;
  for (int k = 0; k < 60; ++k) {
    ModalDecompositionRecord<S, 1> m;
    m.status = ModalStatus::Ok;
    m.a_coarse(0) = S(truth(0, k * kDt) + g(rng));
    m.cov_a(0, 0) = S(4e-4);
    ASSERT_EQ(bank.step(S(kDt), m, rb), StepStatus::Ok);
    ASSERT_EQ(joint.step(S(kDt), m, rj), StepStatus::Ok);
  }
  const double tol = std::is_same<S, float>::value ? 1e-3 : 1e-9;
  for (int r = 0; r < 4; ++r) {
    EXPECT_NEAR(double(bank.mode_state(0)(r)), double(joint.mode_state(0)(r)),
                tol * (1 + std::abs(double(bank.mode_state(0)(r)))));
    EXPECT_NEAR(double(bank.mode_cov(0)(r, r)), double(joint.mode_cov(0)(r, r)),
                tol * double(bank.mode_cov(0)(r, r)) + 1e-12);
  }
}

TYPED_TEST(ModalUkfTest, InitialStateFollowsEq7WithCoupledCovariance) {
  using S = TypeParam;
  const auto cfg = pendulum_config<S, 2>();
  ModalUkfJoint<S, 2> joint(cfg);
  std::mt19937 rng(1);
  const auto m = coarse<S>(0.0, rng);
  ASSERT_EQ(joint.initialize(m), StepStatus::Ok);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(joint.mode_state(i)(0), m.a_coarse(i));
    EXPECT_EQ(joint.mode_state(i)(1), S(0));
    EXPECT_EQ(joint.mode_state(i)(2), cfg.mode[i].omega_radps);
    EXPECT_EQ(joint.mode_state(i)(3), cfg.mode[i].alpha_ps);
  }
  EXPECT_EQ(joint.cov_entry(0, 4), m.cov_a(0, 1));  // the amplitude cross term is kept
  ModalUkfBank<S, 2> bank(cfg);
  ASSERT_EQ(bank.initialize(m), StepStatus::Ok);
  Eigen::Matrix<S, 2, 2> pa;
  bank.amplitude_cov(pa);
  EXPECT_EQ(pa(0, 1), S(0));  // the bank drops it
}

TYPED_TEST(ModalUkfTest, FailedDecompositionGivesBadInputAndNoUpdate) {
  using S = TypeParam;
  ModalUkfBank<S, 2> bank(pendulum_config<S, 2>());
  ModalUkfJoint<S, 2> joint(pendulum_config<S, 2>());
  run_pendulum(bank, 3, 10);
  run_pendulum(joint, 3, 10);
  ModalDecompositionRecord<S, 2> bad;
  bad.status = ModalStatus::TooFewPoints;
  const auto xb = bank.mode_state(1);
  const auto xj = joint.mode_state(1);
  typename ModalUkfBank<S, 2>::Record rb;
  typename ModalUkfJoint<S, 2>::Record rj;
  EXPECT_EQ(bank.update(bad, rb), StepStatus::BadInput);
  EXPECT_EQ(joint.update(bad, rj), StepStatus::BadInput);
  EXPECT_EQ(rb.decomposition, ModalStatus::TooFewPoints);
  EXPECT_FALSE(rj.fused);
  EXPECT_EQ(bank.mode_state(1), xb);
  EXPECT_EQ(joint.mode_state(1), xj);
}

TYPED_TEST(ModalUkfTest, StepBeforeAnyGoodImageDoesNotInitialise) {
  using S = TypeParam;
  ModalUkfBank<S, 2> bank(pendulum_config<S, 2>());
  ModalDecompositionRecord<S, 2> bad;
  bad.status = ModalStatus::IllConditioned;
  typename ModalUkfBank<S, 2>::Record rb;
  EXPECT_EQ(bank.step(S(kDt), bad, rb), StepStatus::BadInput);
  EXPECT_FALSE(bank.initialized());
}

TYPED_TEST(ModalUkfTest, NonPositiveStepIsBadInput) {
  using S = TypeParam;
  ModalUkfJoint<S, 2> joint(pendulum_config<S, 2>());
  run_pendulum(joint, 4, 3);
  const auto x = joint.mode_state(0);
  EXPECT_EQ(joint.predict(S(0)), StepStatus::BadInput);
  EXPECT_EQ(joint.predict(S(NAN)), StepStatus::BadInput);
  EXPECT_EQ(joint.mode_state(0), x);
}

TYPED_TEST(ModalUkfTest, GateRejectsAnOutlierAndLeavesStateUnchanged) {
  using S = TypeParam;
  auto cfg = pendulum_config<S, 2>();
  cfg.gate_nis = S(25);
  ModalUkfJoint<S, 2> joint(cfg);
  run_pendulum(joint, 6, 30);
  std::mt19937 rng(9);
  auto m = coarse<S>(30 * kDt, rng);
  m.a_coarse(0) += S(5);  // 250 sigma
  ASSERT_EQ(joint.predict(S(kDt)), StepStatus::Ok);
  const auto x = joint.mode_state(0);
  typename ModalUkfJoint<S, 2>::Record rec;
  EXPECT_EQ(joint.update(m, rec), StepStatus::Gated);
  EXPECT_GT(rec.nis, S(25));
  EXPECT_EQ(joint.mode_state(0), x);
}

TYPED_TEST(ModalUkfTest, ParameterUncertaintyGrowsWithoutMeasurements) {
  using S = TypeParam;
  auto cfg = pendulum_config<S, 2>();
  cfg.mode[0].q_omega = S(1e-3);
  ModalUkfBank<S, 2> bank(cfg);
  run_pendulum(bank, 7, 5);
  const S before = bank.mode_cov(0)(2, 2);
  for (int k = 0; k < 10; ++k) ASSERT_EQ(bank.predict(S(kDt)), StepStatus::Ok);
  EXPECT_GT(bank.mode_cov(0)(2, 2), before);
}

TYPED_TEST(ModalUkfTest, ShapeReconstructionMatchesEqs8And9) {
  using S = TypeParam;
  Eigen::Matrix<S, 3, 1> a(S(0.5), S(-1), S(2));
  Eigen::Matrix<S, 3, 3> P;
  P << S(2), S(0.3), S(0.1), S(0.3), S(1), S(-0.2), S(0.1), S(-0.2), S(0.5);
  const S phi[6] = {S(1), S(2), S(3), S(-1), S(0), S(0.5)};
  S z[2], var[2];
  const ShapeRecord r = reconstruct_shape<S, 3>(a, P, phi, 2, z, var);
  EXPECT_EQ(r.status, StepStatus::Ok);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Matrix<S, 3, 1> p(phi[3 * k], phi[3 * k + 1], phi[3 * k + 2]);
    EXPECT_NEAR(double(z[k]), double(a.dot(p)), 1e-5);
    EXPECT_NEAR(double(var[k]), double(p.transpose() * P * p), 1e-5);
  }
}

TYPED_TEST(ModalUkfTest, ShapeAtNonFinitePointIsNanAndCounted) {
  using S = TypeParam;
  const Eigen::Matrix<S, 3, 1> a = Eigen::Matrix<S, 3, 1>::Ones();
  const Eigen::Matrix<S, 3, 3> P = Eigen::Matrix<S, 3, 3>::Identity();
  const S phi[6] = {S(1), S(NAN), S(3), S(1), S(1), S(1)};
  S z[2], var[2];
  const ShapeRecord r = reconstruct_shape<S, 3>(a, P, phi, 2, z, var);
  EXPECT_EQ(r.n_nonfinite, 1);
  EXPECT_TRUE(std::isnan(z[0]));
  EXPECT_EQ(z[1], S(3));
  EXPECT_EQ(var[1], S(3));
}

// The bank reports each mode's amplitude and its configuration; an image
// whose amplitude variance makes an innovation variance non-positive is
// refused before any mode changes (NotPosDef, InnovationCholesky).
TYPED_TEST(ModalUkfTest, BankRefusesANonPositiveInnovationVarianceBeforeAnyModeChanges) {
  using S = TypeParam;
  const auto cfg = pendulum_config<S, 2>();
  ModalUkfBank<S, 2> bank(cfg);
  EXPECT_EQ(bank.config().mode[1].omega_radps, cfg.mode[1].omega_radps);
  run_pendulum(bank, 8, 10);
  Eigen::Matrix<S, 2, 1> a;
  bank.amplitudes(a);
  EXPECT_EQ(a(0), bank.mode_state(0)(0));
  EXPECT_EQ(a(1), bank.mode_state(1)(0));
  ASSERT_EQ(bank.predict(S(kDt)), StepStatus::Ok);
  std::mt19937 rng(10);
  auto m = coarse<S>(11 * kDt, rng);
  m.cov_a(1, 1) = -(bank.mode_cov(1)(0, 0) + S(1));  // mode 1's innovation variance -1
  const auto x0 = bank.mode_state(0);
  const auto P0 = bank.mode_cov(0);
  typename ModalUkfBank<S, 2>::Record rec;
  EXPECT_EQ(bank.update(m, rec), StepStatus::NotPosDef);
  EXPECT_EQ(rec.detail, StepDetail::InnovationCholesky);
  EXPECT_FALSE(rec.fused);
  EXPECT_EQ(bank.mode_state(0), x0);  // mode 0, checked first and fine, is not updated either
  EXPECT_EQ(bank.mode_cov(0), P0);
}

// The joint filter refuses an image with a non-finite amplitude covariance
// (BadInput, NonFinite) and keeps its state; it reports its configuration.
TYPED_TEST(ModalUkfTest, JointRefusesANonFiniteAmplitudeCovariance) {
  using S = TypeParam;
  auto cfg = pendulum_config<S, 2>();
  cfg.mode[0].q_a = S(2e-8);
  ModalUkfJoint<S, 2> joint(cfg);
  EXPECT_EQ(joint.config().mode[0].q_a, S(2e-8));
  run_pendulum(joint, 11, 10);
  std::mt19937 rng(12);
  auto m = coarse<S>(11 * kDt, rng);
  m.cov_a(0, 1) = std::numeric_limits<S>::infinity();
  const auto x = joint.mode_state(1);
  typename ModalUkfJoint<S, 2>::Record rec;
  EXPECT_EQ(joint.update(m, rec), StepStatus::BadInput);
  EXPECT_EQ(rec.detail, StepDetail::NonFinite);
  EXPECT_EQ(joint.mode_state(1), x);
}

// A filter whose covariance does not factor (here initialised from an
// image with a negative amplitude variance, which initialise() takes as
// given) refuses the next step at its predict: NotPosDef with detail
// PriorCholesky, nothing fused, the state as it was.
template <typename Filter>
void step_with_a_prior_that_does_not_factor() {
  using S = typename Filter::VecM::Scalar;
  Filter f(pendulum_config<S, 2>());
  std::mt19937 rng(13);
  auto m = coarse<S>(0.0, rng);
  m.cov_a(0, 0) = S(-1);
  typename Filter::Record rec;
  ASSERT_EQ(f.step(S(kDt), m, rec), StepStatus::Ok);  // initialises
  const auto x = f.mode_state(0);
  const auto m1 = coarse<S>(kDt, rng);
  EXPECT_EQ(f.step(S(kDt), m1, rec), StepStatus::NotPosDef);
  EXPECT_EQ(rec.detail, StepDetail::PriorCholesky);
  EXPECT_EQ(rec.decomposition, ModalStatus::Ok);
  EXPECT_FALSE(rec.fused);
  EXPECT_EQ(f.mode_state(0), x);
}

TYPED_TEST(ModalUkfTest, BankStepWithAPriorThatDoesNotFactorIsNotPosDef) {
  step_with_a_prior_that_does_not_factor<ModalUkfBank<TypeParam, 2>>();
}
TYPED_TEST(ModalUkfTest, JointStepWithAPriorThatDoesNotFactorIsNotPosDef) {
  step_with_a_prior_that_does_not_factor<ModalUkfJoint<TypeParam, 2>>();
}
