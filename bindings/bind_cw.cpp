#include "bind.hpp"
#include "fsw/dynamics/cw.hpp"
#include "validate.hpp"

using namespace bind_detail;

void bind_cw(py::module_& m) {
  m.attr("MU_EARTH") = fsw::kMuEarth;
  m.attr("EARTH_RADIUS") = fsw::kEarthRadius;
  m.def(
      "orbit_rate", [](double radius) { return fsw::orbit_rate(positive(radius, "radius_m")); }, py::arg("radius_m"),
      "Circular-orbit rate n = sqrt(mu / a^3) [rad/s]; a is the radius [m].");
  m.def(
      "cw_stm", [](double n, double t) { return to_numpy(fsw::cw_stm(positive(n, "n_radps"), finite(t, "t_s"))); },
      py::arg("n_radps"), py::arg("t_s"), "CW state transition matrix Phi(t), state [r_hill_m, v_hill_mps].");
  m.def(
      "cw_accel_response",
      [](double n, double t) { return to_numpy(fsw::cw_accel_response(positive(n, "n_radps"), finite(t, "t_s"))); },
      py::arg("n_radps"), py::arg("t_s"), "6x3 response Gamma(t) to a Hill-frame acceleration held over [0, t].");

  using P = fsw::CwPropagator<double>;
  py::class_<P>(m, "CwPropagator", "Fixed-step CW propagator with the constant-acceleration term.")
      .def(py::init([](double n, double dt) { return P(positive(n, "n_radps"), positive(dt, "dt_s")); }),
           py::arg("n_radps"), py::arg("dt_s"))
      .def(
          "step",
          [](const P& p, const Arr& state, const Arr& a) {
            return to_numpy(p.step(vec<6>(state, "state"), Eigen::Vector3d(vec<3>(a, "a_hill_mps2"))));
          },
          py::arg("state"), py::arg("a_hill_mps2"),
          "state [r_hill_m(3), v_hill_mps(3)] after one step with acceleration a_hill_mps2 held.")
      .def_property_readonly("stm", [](const P& p) { return to_numpy(p.stm()); })
      .def_property_readonly("accel_response", [](const P& p) { return to_numpy(p.accel_response()); })
      .def_property_readonly("n_radps", &P::orbit_rate_radps)
      .def_property_readonly("dt_s", &P::dt_s);
}
