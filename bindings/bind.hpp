// One bind_<concept> function per concept; module.cpp calls each once.
#pragma once

#include <pybind11/pybind11.h>

void bind_so3(pybind11::module_& m);
void bind_cw(pybind11::module_& m);
