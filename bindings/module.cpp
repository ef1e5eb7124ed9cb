// The Python module over the flight library. Thin: converts and validates,
// adds no logic.
#include "bind.hpp"

PYBIND11_MODULE(fsw_bindings, m) {
  m.doc() =
      "Flight software core (fsw/) for the bench. Frames and units as in DESIGN.md: Hill frame "
      "(x radial, y along-track, z orbit normal), SI units, quaternions scalar-first [w, x, y, z] "
      "rotating body vectors into the Hill frame.";
  bind_so3(m);
  bind_cw(m);
}
