// One bind_<concept> function per concept; module.cpp calls each once.
#pragma once

#include <pybind11/pybind11.h>

void bind_so3(pybind11::module_& m);
void bind_cw(pybind11::module_& m);
void bind_link(pybind11::module_& m);
void bind_nav(pybind11::module_& m);
void bind_nav_replay(pybind11::module_& m);
void bind_flight_app(pybind11::module_& m);
void bind_blr(pybind11::module_& m);
void bind_modal(pybind11::module_& m);
void bind_features(pybind11::module_& m);
#ifdef PROXOPS_HAVE_VISION
void bind_vision(pybind11::module_& m);  // OpenCV found
#endif
