// Explicit instantiations of the flight application, float and double: the
// flight executable, the bindings and the tests link to these.
#include "fsw/app/flight_app.hpp"

namespace fsw {
template class FlightApp<double>;
template class FlightApp<float>;
}  // namespace fsw
