// Thruster learner (fsw/blr.hpp): Bayes linear regression over a sliding
// window. Inputs are the eight valve states plus bias (9) or with pairwise
// products (37); outputs are the change in body linear velocity [m/s] (3) and
// body angular velocity [rad/s] (3) over one firing interval.
#include <cstdint>
#include <string>

#include "bind.hpp"
#include "fsw/thrusters/blr.hpp"
#include "validate.hpp"

using namespace bind_detail;

namespace {

// The features of valve configuration mask (bit i = valve i).
template <bool kPairs>
auto features_of(int mask) {
  if (mask < 0 || mask > 255) throw py::value_error("mask: valve configuration must be in 0..255");
  return fsw::ValveFeatures<double, kPairs>::from_mask(std::uint8_t(mask));
}

template <typename Blr>
py::dict add_record_dict(const typename Blr::AddRecord& r) {
  py::dict d;
  d["status"] = fsw::to_string(r.status);
  d["entered"] = r.entered;
  d["evicted"] = r.evicted;
  d["refreshed"] = r.refreshed;
  d["count"] = r.count;
  return d;
}

template <typename Blr>
auto prediction_tuple(const typename Blr::Prediction& p) {
  if (p.status == fsw::StepStatus::BadInput) throw py::value_error("x: not finite");
  return py::make_tuple(to_numpy(p.mean), to_numpy(p.variance), fsw::to_string(p.status));
}

template <typename Blr>
Blr make_blr(double prior_precision, const py::object& noise_var, bool estimate_noise) {
  typename Blr::Config c;
  if (!std::isfinite(prior_precision) || prior_precision < 0)
    throw py::value_error("prior_precision: must be finite and >= 0");
  c.prior_precision = prior_precision;
  if (!noise_var.is_none()) {
    c.noise_var = vec<Blr::kOutputs>(noise_var.cast<Arr>(), "noise_var");
    if ((c.noise_var.array() < 0).any()) throw py::value_error("noise_var: must be >= 0");
  }
  c.estimate_noise = estimate_noise;
  return Blr(c);
}

// Samples in and out of the window.
template <typename Blr, bool kPairs>
void def_learning(py::class_<Blr>& cls) {
  constexpr int D = Blr::kInputs;
  constexpr int K = Blr::kOutputs;
  cls.def(
         "add",
         [](Blr& b, const Arr& x, const Arr& y) { return add_record_dict<Blr>(b.add(vec<D>(x, "x"), vec<K>(y, "y"))); },
         py::arg("x"), py::arg("y"),
         "Enter a sample: x features, y = [dv_b_mps(3), dw_b_rps(3)]. Evicts the oldest when full.")
      .def(
          "add_mask",
          [](Blr& b, int mask, const Arr& y) {
            return add_record_dict<Blr>(b.add(features_of<kPairs>(mask), vec<K>(y, "y")));
          },
          py::arg("mask"), py::arg("y"), "add() with the features of valve configuration mask (bit i = valve i).")
      .def("remove_oldest", [](Blr& b) { return std::string(fsw::to_string(b.remove_oldest())); })
      .def("reset", &Blr::reset);
}

// What the learner predicts for a configuration, and how well it knows it.
template <typename Blr, bool kPairs>
void def_prediction(py::class_<Blr>& cls) {
  constexpr int D = Blr::kInputs;
  cls.def(
         "predict", [](Blr& b, const Arr& x) { return prediction_tuple<Blr>(b.predict(vec<D>(x, "x"))); }, py::arg("x"),
         "(mean (6,), predictive variance (6,), status) at features x.")
      .def(
          "predict_mask", [](Blr& b, int mask) { return prediction_tuple<Blr>(b.predict(features_of<kPairs>(mask))); },
          py::arg("mask"), "predict() at valve configuration mask.")
      .def(
          "mean_and_its_variance_mask",
          [](Blr& b, int mask) {
            const auto p = b.predict(features_of<kPairs>(mask));
            if (p.status == fsw::StepStatus::BadInput) throw py::value_error("x: not finite");
            return py::make_tuple(to_numpy(p.mean), to_numpy(typename Blr::VecY(p.noise_var * p.leverage)));
          },
          py::arg("mask"),
          "(posterior mean (6,), its variance s_k^2 x^T A^-1 x (6,)) at valve configuration mask: how well the "
          "learner knows this configuration's effect, without the noise of a new measurement.");
}

// The posterior and the window's sizes.
template <typename Blr, bool kPairs>
void def_posterior(py::class_<Blr>& cls) {
  constexpr int D = Blr::kInputs;
  cls.def_property_readonly(
         "theta",
         [](Blr& b) {
           b.refresh_posterior();
           return to_numpy(b.theta());
         },
         "Posterior mean weights (D, 6): column k maps features to output k.")
      .def_property_readonly(
          "information", [](const Blr& b) { return to_numpy(b.information()); },
          "Shared unscaled information matrix A = lambda I + sum x x^T (D, D).")
      .def_property_readonly("noise_var",
                             [](Blr& b) {
                               b.refresh_posterior();
                               return to_numpy(b.noise_var());
                             })
      .def_property_readonly("count", &Blr::count)
      .def_property_readonly("refresh_count", [](const Blr& b) { return std::uint64_t(b.refresh_count()); })
      .def_property_readonly_static("inputs", [](py::object) { return D; })
      .def_property_readonly_static("window", [](py::object) { return Blr::kWindow; })
      .def_static(
          "features", [](int mask) { return to_numpy(features_of<kPairs>(mask)); }, py::arg("mask"),
          "Feature vector of valve configuration mask: [v0..v7, 1] (+ pairwise products v_i v_j, i<j).");
}

template <typename Blr, bool kPairs>
void bind_one(py::module_& m, const char* name, const char* doc) {
  py::class_<Blr> cls(m, name, doc);
  cls.def(py::init(&make_blr<Blr>), py::arg("prior_precision") = 1e-3, py::arg("noise_var") = py::none(),
          py::arg("estimate_noise") = true,
          "prior_precision lambda [1/x^2] (prior theta_k ~ N(0, s_k^2/lambda I)); noise_var s_k^2 (6,) "
          "[(m/s)^2 x3, (rad/s)^2 x3] used when estimate_noise is False or the window holds <= D samples.");
  def_learning<Blr, kPairs>(cls);
  def_prediction<Blr, kPairs>(cls);
  def_posterior<Blr, kPairs>(cls);
}

}  // namespace

void bind_blr(py::module_& m) {
  bind_one<fsw::ThrusterBlr<double, 30>, false>(
      m, "ThrusterBlr", "Bayes linear regression, 8 valves + bias -> [dv_b_mps(3), dw_b_rps(3)], window 30.");
  bind_one<fsw::ThrusterBlr<double, 100>, false>(m, "ThrusterBlrW100", "As ThrusterBlr with window 100.");
  bind_one<fsw::ThrusterBlrPairs<double, 30>, true>(
      m, "ThrusterBlrPairs", "As ThrusterBlr with the 28 pairwise valve products added (37 inputs), window 30.");
}
