// Explicit instantiations of the log replay through the navigation filter,
// float and double: the bindings and the tests link to these.
#include "fsw/app/nav_replay.hpp"

namespace fsw {
template class NavReplay<double>;
template class NavReplay<float>;
}  // namespace fsw
