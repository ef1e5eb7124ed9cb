// RAM taken by each flight object, for the size report: one symbol per
// object whose size is the object's, in a section that is not loaded
// (.fw_sizes, INFO in the linker script). Nothing here is in the image.
#include "fsw/app/flight_app.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"
#include "fsw/thrusters/blr.hpp"

#define FW_SIZE(name, ...) \
  extern "C" __attribute__((section(".fw_sizes"), used)) const unsigned char fw_size_##name[sizeof(__VA_ARGS__)] = {};

using App = fsw::FlightApp<float>;
FW_SIZE(flight_app, App)
FW_SIZE(nav_ukf, App::Nav)
FW_SIZE(modal_tracker, App::Modal)
FW_SIZE(modal_acquisition, App::Modal::Acquisition)
FW_SIZE(modal_filter, App::Modal::Filter)
FW_SIZE(modal_decomposition, App::Modal::Decomposition)
FW_SIZE(learner, fsw::ThrusterBlr<float, 30>)
FW_SIZE(deframer, fsw::Deframer)
FW_SIZE(framer, fsw::Framer)
FW_SIZE(tx_buffer, std::uint8_t[App::kTxCapacity])
