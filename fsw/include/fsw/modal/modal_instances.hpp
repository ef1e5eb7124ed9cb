// The sizes the flight core compiles the modal estimator at, in both scalar
// builds: 3 modes (pendulum), 10 (the flight application), 50 (structure).
// FSW_MODAL_INSTANCES(X) expands X(S, M) once per pair: the headers declare
// their classes at these sizes with it (extern template) and fsw/src/modal/
// defines them with it, so the list is written once.
#pragma once

#define FSW_MODAL_INSTANCES(X) X(double, 3) X(float, 3) X(double, 10) X(float, 10) X(double, 50) X(float, 50)
