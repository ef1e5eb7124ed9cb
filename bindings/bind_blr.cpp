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

template <typename Blr, bool kPairs>
void bind_one(py::module_& m, const char* name, const char* doc) {
  constexpr int D = Blr::kInputs;
  constexpr int K = Blr::kOutputs;
  using Feat = fsw::ValveFeatures<double, kPairs>;
  auto mask_of = [](int mask) {
    if (mask < 0 || mask > 255) throw py::value_error("mask: valve configuration must be in 0..255");
    return Feat::from_mask(std::uint8_t(mask));
  };
  auto rec_dict = [](const typename Blr::AddRecord& r) {
    py::dict d;
    d["status"] = fsw::to_string(r.status);
    d["entered"] = r.entered;
    d["evicted"] = r.evicted;
    d["refreshed"] = r.refreshed;
    d["count"] = r.count;
    return d;
  };
  auto pred_tuple = [](const typename Blr::Prediction& p) {
    if (p.status == fsw::StepStatus::BadInput) throw py::value_error("x: not finite");
    return py::make_tuple(to_numpy(p.mean), to_numpy(p.variance), fsw::to_string(p.status));
  };
  py::class_<Blr>(m, name, doc)
      .def(py::init([](double prior_precision, py::object noise_var, bool estimate_noise) {
             typename Blr::Config c;
             if (!std::isfinite(prior_precision) || prior_precision < 0)
               throw py::value_error("prior_precision: must be finite and >= 0");
             c.prior_precision = prior_precision;
             if (!noise_var.is_none()) {
               c.noise_var = vec<K>(noise_var.cast<Arr>(), "noise_var");
               if ((c.noise_var.array() < 0).any()) throw py::value_error("noise_var: must be >= 0");
             }
             c.estimate_noise = estimate_noise;
             return Blr(c);
           }),
           py::arg("prior_precision") = 1e-3, py::arg("noise_var") = py::none(), py::arg("estimate_noise") = true,
           "prior_precision lambda [1/x^2] (prior theta_k ~ N(0, s_k^2/lambda I)); noise_var s_k^2 (6,) "
           "[(m/s)^2 x3, (rad/s)^2 x3] used when estimate_noise is False or the window holds <= D samples.")
      .def(
          "add",
          [rec_dict](Blr& b, const Arr& x, const Arr& y) { return rec_dict(b.add(vec<D>(x, "x"), vec<K>(y, "y"))); },
          py::arg("x"), py::arg("y"),
          "Enter a sample: x features, y = [dv_b_mps(3), dw_b_rps(3)]. Evicts the oldest when full.")
      .def(
          "add_mask",
          [rec_dict, mask_of](Blr& b, int mask, const Arr& y) {
            return rec_dict(b.add(mask_of(mask), vec<K>(y, "y")));
          },
          py::arg("mask"), py::arg("y"), "add() with the features of valve configuration mask (bit i = valve i).")
      .def("remove_oldest", [](Blr& b) { return std::string(fsw::to_string(b.remove_oldest())); })
      .def(
          "predict", [pred_tuple](Blr& b, const Arr& x) { return pred_tuple(b.predict(vec<D>(x, "x"))); }, py::arg("x"),
          "(mean (6,), predictive variance (6,), status) at features x.")
      .def(
          "predict_mask", [pred_tuple, mask_of](Blr& b, int mask) { return pred_tuple(b.predict(mask_of(mask))); },
          py::arg("mask"), "predict() at valve configuration mask.")
      .def(
          "mean_and_its_variance_mask",
          [mask_of](Blr& b, int mask) {
            const auto p = b.predict(mask_of(mask));
            if (p.status == fsw::StepStatus::BadInput) throw py::value_error("x: not finite");
            return py::make_tuple(to_numpy(p.mean), to_numpy(typename Blr::VecY(p.noise_var * p.leverage)));
          },
          py::arg("mask"),
          "(posterior mean (6,), its variance s_k^2 x^T A^-1 x (6,)) at valve configuration mask: how well the "
          "learner knows this configuration's effect, without the noise of a new measurement.")
      .def_property_readonly(
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
      .def("reset", &Blr::reset)
      .def_static(
          "features", [mask_of](int mask) { return to_numpy(mask_of(mask)); }, py::arg("mask"),
          "Feature vector of valve configuration mask: [v0..v7, 1] (+ pairwise products v_i v_j, i<j).");
}

}  // namespace

void bind_blr(py::module_& m) {
  bind_one<fsw::ThrusterBlr<double, 30>, false>(
      m, "ThrusterBlr", "Bayes linear regression, 8 valves + bias -> [dv_b_mps(3), dw_b_rps(3)], window 30.");
  bind_one<fsw::ThrusterBlr<double, 100>, false>(m, "ThrusterBlrW100", "As ThrusterBlr with window 100.");
  bind_one<fsw::ThrusterBlrPairs<double, 30>, true>(
      m, "ThrusterBlrPairs", "As ThrusterBlr with the 28 pairwise valve products added (37 inputs), window 30.");
}
