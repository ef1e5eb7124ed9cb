// The firmware's flight core, float only: the flight application (link in,
// telemetry out; the components above are linked, not compiled again).
#include "fsw/app/flight_app.hpp"

namespace fsw {
template class FlightApp<float>;
}  // namespace fsw
