// Modal estimator (Lichter and Dubowsky, range images): decomposition of a range image, the bank of
// decoupled per-mode UKFs, the joint UKF, shape reconstruction, and the
// frequency acquisition (256-image history). Bound in
// double for the mode counts the bench uses: 3 (pendulum), 10 and 50
// (structure); classes carry the count in their name (ModalDecomposition10).
//
// Range-image arrays may hold NaN (missing pixels): the flight code skips and
// counts those points, so only shapes are checked here.
#include <memory>
#include <string>

#include "bind.hpp"
#include "fsw/modal/modal_acquisition.hpp"
#include "fsw/modal/modal_decomposition.hpp"
#include "fsw/modal/modal_shape.hpp"
#include "fsw/modal/modal_ukf.hpp"
#include "validate.hpp"

using namespace bind_detail;

namespace {

template <int M>
Eigen::Matrix<double, M, 1> mvec(const Arr& a, const char* name) {
  return vec<M>(a, name);
}

// Shape (n, M) array of point mode-shape values; returns n.
template <int M>
int check_rows(const Arr& phi, const char* name) {
  if (phi.ndim() != 2 || phi.shape(1) != M) {
    throw py::value_error(std::string(name) + ": expected shape (n, " + std::to_string(M) + "), got " + shape_str(phi));
  }
  return static_cast<int>(phi.shape(0));
}

template <int M>
void check_len(const Arr& a, int n, const char* name) {
  if (a.ndim() != 1 || a.shape(0) != n) {
    throw py::value_error(std::string(name) + ": expected shape (" + std::to_string(n) + ",), got " + shape_str(a));
  }
}

template <int M>
fsw::ModalFilterConfig<double, M> filter_config(const Arr& omega, const Arr& alpha, const Arr& sv, const Arr& sw,
                                                const Arr& sa, const Arr& qa, const Arr& qv, const Arr& qw,
                                                const Arr& qal, double gate, double ut_alpha, double ut_beta,
                                                double ut_kappa) {
  fsw::ModalFilterConfig<double, M> cfg;
  const auto w = mvec<M>(omega, "omega_radps"), al = mvec<M>(alpha, "alpha_ps"), v0 = mvec<M>(sv, "sigma_v0_ps"),
             w0 = mvec<M>(sw, "sigma_omega0_radps"), a0 = mvec<M>(sa, "sigma_alpha0_ps"), q1 = mvec<M>(qa, "q_a"),
             q2 = mvec<M>(qv, "q_v"), q3 = mvec<M>(qw, "q_omega"), q4 = mvec<M>(qal, "q_alpha");
  for (int i = 0; i < M; ++i) {
    cfg.mode[i].omega_radps = w(i);
    cfg.mode[i].alpha_ps = al(i);
    cfg.mode[i].sigma_v0_ps = v0(i);
    cfg.mode[i].sigma_omega0_radps = w0(i);
    cfg.mode[i].sigma_alpha0_ps = a0(i);
    cfg.mode[i].q_a = q1(i);
    cfg.mode[i].q_v = q2(i);
    cfg.mode[i].q_omega = q3(i);
    cfg.mode[i].q_alpha = q4(i);
  }
  cfg.gate_nis = finite(gate, "gate_nis");
  cfg.ut.alpha = positive(ut_alpha, "ut_alpha");
  cfg.ut.beta = finite(ut_beta, "ut_beta");
  cfg.ut.kappa = finite(ut_kappa, "ut_kappa");
  return cfg;
}

template <typename Rec>
py::dict step_dict(const Rec& r) {
  py::dict d;
  d["status"] = fsw::to_string(r.status);
  d["detail"] = fsw::to_string(r.detail);
  d["decomposition"] = fsw::to_string(r.decomposition);
  d["fused"] = r.fused;
  d["innovation"] = to_numpy(r.innovation);
  d["innovation_var"] = to_numpy(r.innovation_var);
  d["nis"] = r.nis;
  d["n_gated"] = r.n_gated;
  return d;
}

template <typename F, int M>
void bind_filter(py::module_& m, const std::string& name, const char* doc) {
  using Rec = typename F::Record;
  using D = fsw::ModalDecompositionRecord<double, M>;
  py::class_<F, std::unique_ptr<F>>(m, name.c_str(), doc)
      .def(py::init([](const Arr& omega, const Arr& alpha, const Arr& sv, const Arr& sw, const Arr& sa, const Arr& qa,
                       const Arr& qv, const Arr& qw, const Arr& qal, double gate, double ua, double ub, double uk) {
             return std::make_unique<F>(filter_config<M>(omega, alpha, sv, sw, sa, qa, qv, qw, qal, gate, ua, ub, uk));
           }),
           py::arg("omega_radps"), py::arg("alpha_ps"), py::arg("sigma_v0_ps"), py::arg("sigma_omega0_radps"),
           py::arg("sigma_alpha0_ps"), py::arg("q_a"), py::arg("q_v"), py::arg("q_omega"), py::arg("q_alpha"),
           py::arg("gate_nis") = 0.0, py::arg("ut_alpha") = 1.0, py::arg("ut_beta") = 2.0, py::arg("ut_kappa") = 0.0,
           "Per-mode arrays (M,): expected frequency [rad/s] and damping [1/s] (eq. 7), initial 1-sigma of "
           "rate [1/s], frequency [rad/s], damping [1/s], process-noise densities (Q = diag(q) dt).")
      .def_property_readonly("initialized", &F::initialized)
      .def(
          "initialize", [](F& f, const D& r) { return std::string(fsw::to_string(f.initialize(r))); },
          py::arg("record"))
      .def(
          "predict", [](F& f, double dt) { return std::string(fsw::to_string(f.predict(dt))); }, py::arg("dt_s"))
      .def(
          "update",
          [](F& f, const D& r) {
            Rec rec;
            f.update(r, rec);
            return step_dict(rec);
          },
          py::arg("record"))
      .def(
          "step",
          [](F& f, double dt, const D& r) {
            Rec rec;
            f.step(dt, r, rec);
            return step_dict(rec);
          },
          py::arg("dt_s"), py::arg("record"),
          "Predict over dt_s then fuse the image's decomposition; the first Ok image initialises (eq. 7).")
      .def_property_readonly(
          "state",
          [](const F& f) {
            Eigen::Matrix<double, M, 4> s;
            for (int i = 0; i < M; ++i) s.row(i) = f.mode_state(i).transpose();
            return to_numpy(s);
          },
          "(M, 4): per mode [A, V [1/s], omega [rad/s], alpha [1/s]].")
      .def_property_readonly("state_std",
                             [](const F& f) {
                               Eigen::Matrix<double, M, 4> s;
                               for (int i = 0; i < M; ++i) s.row(i) = f.mode_cov(i).diagonal().cwiseSqrt().transpose();
                               return to_numpy(s);
                             })
      .def_property_readonly("amplitudes",
                             [](const F& f) {
                               Eigen::Matrix<double, M, 1> a;
                               f.amplitudes(a);
                               return to_numpy(a);
                             })
      .def_property_readonly("amplitude_cov", [](const F& f) {
        Eigen::Matrix<double, M, M> p;
        f.amplitude_cov(p);
        return to_numpy(p);
      });
}

template <typename F, int M>
int replay(fsw::ModalAcquisition<double, M, 256>& a, F& f) {
  typename F::Record rec;
  const auto cfg = f.config();  // copy: reset() takes it again
  return a.replay_into(f, cfg, rec);
}

template <int M>
void bind_acquisition(py::module_& m) {
  using A = fsw::ModalAcquisition<double, M, 256>;
  using R = fsw::ModalDecompositionRecord<double, M>;
  auto vec_of = [](const A& a, double (A::*get)(int) const) {
    Eigen::Matrix<double, M, 1> v;
    for (int i = 0; i < M; ++i) v(i) = (a.*get)(i);
    return to_numpy(v);
  };
  py::class_<A, std::unique_ptr<A>>(m, ("ModalAcquisition" + std::to_string(M)).c_str(),
                                    "Frequency acquisition: RELAX over up to 256 images' coarse amplitudes.")
      .def(py::init([](const Arr& omega, const Arr& sigma, double grid_sigmas, int cycles, int min_images) {
             fsw::ModalAcquisitionConfig<double, M> c;
             const auto w = mvec<M>(omega, "omega_prior_radps"), sw = mvec<M>(sigma, "sigma_omega_radps");
             for (int i = 0; i < M; ++i) {
               c.omega_prior_radps[i] = positive(w(i), "omega_prior_radps");
               c.sigma_omega_radps[i] = positive(sw(i), "sigma_omega_radps");
             }
             c.grid_sigmas = positive(grid_sigmas, "grid_sigmas");
             if (cycles < 1 || cycles > 100) throw py::value_error("cycles: must be in [1, 100]");
             if (min_images < 3) throw py::value_error("min_images: must be at least 3");
             c.cycles = cycles;
             c.min_images = min_images;
             return std::make_unique<A>(c);
           }),
           py::arg("omega_prior_radps"), py::arg("sigma_omega_radps"), py::arg("grid_sigmas") = 3.0,
           py::arg("cycles") = 3, py::arg("min_images") = 3,
           "A priori frequencies and their 1-sigma (M,) [rad/s]; the grid spans +-grid_sigmas sigma in 201 "
           "points; cycles RELAX passes over the modes.")
      .def(
          "add", [](A& a, double t, const R& r) { return std::string(fsw::to_string(a.add(t, r))); }, py::arg("t_s"),
          py::arg("record"), "Stores one image's decomposition; returns the status.")
      .def("search", [](A& a) { return std::string(fsw::to_string(a.search())); })
      .def("start_search", [](A& a) { return std::string(fsw::to_string(a.start_search())); })
      .def("search_step", [](A& a) { return std::string(fsw::to_string(a.search_step())); })
      .def_property_readonly("images", &A::images)
      .def_property_readonly("done", &A::done)
      .def_property_readonly("omega", [vec_of](const A& a) { return vec_of(a, &A::omega); })
      .def_property_readonly("cos_amp", [vec_of](const A& a) { return vec_of(a, &A::cos_amp); })
      .def_property_readonly("sin_amp", [vec_of](const A& a) { return vec_of(a, &A::sin_amp); })
      .def(
          "coarse",
          [](A& a, int k) {
            if (k < 0 || k >= a.images()) throw py::index_error("coarse: image index out of range");
            R r;
            a.coarse(k, r);
            return r;
          },
          py::arg("k"), "Image k's coarse amplitudes and covariance rebuilt from the stored information.")
      .def("replay_into", &replay<fsw::ModalUkfJoint<double, M>, M>, py::arg("filter"),
           "Resets the filter to its own configuration and steps it over every stored image; returns the "
           "number fused.")
      .def("replay_into", &replay<fsw::ModalUkfBank<double, M>, M>, py::arg("filter"));
}

template <int M>
void bind_decomposition_record(py::module_& m) {
  using R = fsw::ModalDecompositionRecord<double, M>;
  py::class_<R>(m, ("ModalDecompositionRecord" + std::to_string(M)).c_str(), "Result of one decomposition (eqs. 3-4).")
      .def_property_readonly("status", [](const R& r) { return std::string(fsw::to_string(r.status)); })
      .def_property_readonly("ok", &R::ok)
      .def_property_readonly("a_coarse", [](const R& r) { return to_numpy(r.a_coarse); })
      .def_property_readonly("cov_a", [](const R& r) { return to_numpy(r.cov_a); })
      .def_readonly("condition_number", &R::condition_number)
      .def_readonly("eig_min", &R::eig_min)
      .def_readonly("eig_max", &R::eig_max)
      .def_readonly("sigma2_residual_m2", &R::sigma2_residual_m2)
      .def_readonly("n_used", &R::n_used)
      .def_readonly("n_nonfinite", &R::n_nonfinite)
      .def_readonly("n_bad_variance", &R::n_bad_variance)
      .def_readonly("per_point_variance", &R::per_point_variance);
}

template <int M>
void bind_decomposition(py::module_& m) {
  using D = fsw::ModalDecomposition<double, M>;
  using R = fsw::ModalDecompositionRecord<double, M>;
  py::class_<D, std::unique_ptr<D>>(m, ("ModalDecomposition" + std::to_string(M)).c_str(),
                                    "Streaming modal decomposition of one range image (eqs. 2-4).")
      .def(py::init([](double sigma_e, double max_cond, int min_points) {
             fsw::ModalDecompositionConfig<double> c;
             if (!(sigma_e >= 0.0) || !std::isfinite(sigma_e)) throw py::value_error("sigma_e_m: must be >= 0");
             c.sigma_e_m = sigma_e;
             c.max_condition = positive(max_cond, "max_condition");
             c.min_points = min_points;
             return std::make_unique<D>(c);
           }),
           py::arg("sigma_e_m") = 0.0, py::arg("max_condition") = 1e10, py::arg("min_points") = 0,
           "sigma_e_m: equal deflection noise [m] for eq. 4b (0: residual estimate); max_condition: bound on "
           "cond(M_Y); min_points: minimum usable points (at least M + 1).")
      .def("reset", &D::reset)
      .def(
          "add_points",
          [](D& d, const Arr& phi, const Arr& z, const py::object& var) {
            const int n = check_rows<M>(phi, "phi");
            check_len<M>(z, n, "z_m");
            if (var.is_none()) return d.add_points(phi.data(), z.data(), nullptr, n);
            const Arr v = var.cast<Arr>();
            check_len<M>(v, n, "var_m2");
            return d.add_points(phi.data(), z.data(), v.data(), n);
          },
          py::arg("phi"), py::arg("z_m"), py::arg("var_m2") = py::none(),
          "Adds n points: phi (n, M) mode-shape values, z_m (n,) deflections [m], var_m2 (n,) variances "
          "[m^2] or None (eq. 4b). NaN points are skipped and counted. Returns the number used.")
      .def(
          "solve",
          [](D& d) {
            R r;
            d.solve(r);
            return r;
          },
          "Eqs. 3-4 for the points added since reset(); returns the record.")
      .def(
          "decompose",
          [](D& d, const Arr& phi, const Arr& z, const py::object& var) {
            const int n = check_rows<M>(phi, "phi");
            check_len<M>(z, n, "z_m");
            d.reset();
            if (var.is_none()) {
              d.add_points(phi.data(), z.data(), nullptr, n);
            } else {
              const Arr v = var.cast<Arr>();
              check_len<M>(v, n, "var_m2");
              d.add_points(phi.data(), z.data(), v.data(), n);
            }
            R r;
            d.solve(r);
            return r;
          },
          py::arg("phi"), py::arg("z_m"), py::arg("var_m2") = py::none(), "reset + add_points + solve.");
}

template <int M>
void bind_reconstruct_shape(py::module_& m) {
  m.def(("reconstruct_shape" + std::to_string(M)).c_str(),
        [](const Arr& a, const Arr& cov, const Arr& phi) {
          const auto av = mvec<M>(a, "a");
          const auto P = mat<M, M>(cov, "cov_a");
          const int n = check_rows<M>(phi, "phi");
          py::array_t<double> z(n), var(n);
          fsw::reconstruct_shape<double, M>(av, P, phi.data(), n, z.mutable_data(), var.mutable_data());
          return py::make_tuple(z, var);
        },
        py::arg("a"), py::arg("cov_a"), py::arg("phi"),
        "Eqs. 8-9: (z_m, var_m2) at the points whose mode-shape rows are phi (n, M).");
}

// Everything of one modal size M, in the order its signatures need.
template <int M>
void bind_size(py::module_& m) {
  const std::string sfx = std::to_string(M);
  bind_decomposition_record<M>(m);
  bind_decomposition<M>(m);
  bind_filter<fsw::ModalUkfBank<double, M>, M>(m, "ModalUkfBank" + sfx,
                                               "Bank of decoupled per-mode 4-state UKFs (eqs. 5-7).");
  bind_filter<fsw::ModalUkfJoint<double, M>, M>(m, "ModalUkfJoint" + sfx,
                                                "Joint 4M-state UKF with the coupled measurement covariance.");
  bind_reconstruct_shape<M>(m);
  bind_acquisition<M>(m);
}

}  // namespace

void bind_modal(py::module_& m) {
  bind_size<3>(m);
  bind_size<10>(m);
  bind_size<50>(m);
  m.attr("MODAL_SIZES") = py::make_tuple(3, 10, 50);
}
