// The Python module over the flight library. Thin: converts and validates,
// adds no logic.
#include "bind.hpp"

PYBIND11_MODULE(fsw_bindings, m) {
  m.doc() =
      "Flight software core (fsw/) for the bench. Frames and units as in docs/CONVENTIONS.md: Hill frame "
      "(x radial, y along-track, z orbit normal), SI units, quaternions scalar-first [w, x, y, z] "
      "rotating body vectors into the Hill frame.";
  bind_so3(m);
  bind_cw(m);
  bind_link(m);
  bind_nav(m);
  bind_nav_replay(m);
  bind_flight_app(m);
  bind_blr(m);
  bind_modal(m);
  bind_features(m);
#ifdef PROXOPS_HAVE_VISION
  bind_vision(m);
#endif
}
