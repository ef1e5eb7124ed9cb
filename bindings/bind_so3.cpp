#include "bind.hpp"
#include "fsw/dynamics/hill_attitude.hpp"
#include "fsw/math/so3.hpp"
#include "validate.hpp"

using namespace bind_detail;

void bind_so3(py::module_& m) {
  m.def(
      "so3_exp", [](const Arr& phi) { return quat_to_numpy(fsw::exp(vec<3>(phi, "phi"))); }, py::arg("phi"),
      "Rotation vector phi [rad] -> unit quaternion [w, x, y, z].");
  m.def(
      "so3_log", [](const Arr& q) { return to_numpy(fsw::log(quat(q, "q"))); }, py::arg("q"),
      "Unit quaternion [w, x, y, z] -> rotation vector [rad], angle in [0, pi].");
  m.def(
      "boxplus",
      [](const Arr& q, const Arr& d) {
        return quat_to_numpy(fsw::boxplus(quat(q, "q"), Eigen::Vector3d(vec<3>(d, "delta"))));
      },
      py::arg("q"), py::arg("delta"), "q [+] delta = q * Exp(delta); delta [rad] in the body frame.");
  m.def(
      "boxminus", [](const Arr& q1, const Arr& q0) { return to_numpy(fsw::boxminus(quat(q1, "q1"), quat(q0, "q0"))); },
      py::arg("q1"), py::arg("q0"), "q1 [-] q0 = Log(q0^-1 * q1) [rad], body frame of q0.");
  m.def(
      "rotation_matrix", [](const Arr& q) { return to_numpy(fsw::rotation_matrix(quat(q, "q"))); }, py::arg("q"),
      "3x3 matrix taking body vectors into the Hill frame.");
  m.def(
      "propagate_attitude",
      [](const Arr& q_hb, const Arr& omega, double n, double dt) {
        return quat_to_numpy(fsw::propagate_attitude(quat(q_hb, "q_hb"),
                                                     Eigen::Vector3d(vec<3>(omega, "omega_bi_b_rps")),
                                                     finite(n, "n_radps"), finite(dt, "dt_s")));
      },
      py::arg("q_hb"), py::arg("omega_bi_b_rps"), py::arg("n_radps"), py::arg("dt_s"),
      "One step of q_HB from a gyro rate omega_BI_B [rad/s] held over dt [s], with the Hill "
      "frame turning at n [rad/s] about its z axis.");
}
