// Uses the installed flight library as an outside project would: frames one
// command, deframes it again (deframer.cpp, compiled into the library) and
// takes the CW transition matrix at t = 0 (a template instantiated in the
// library). Exit 0 when both give back what went in.
#include <cstdint>
#include <cstdio>

#include "fsw/dynamics/cw.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"

int main() {
  fsw::Framer framer(fsw::Direction::ToFlight);
  fsw::CmdConfigMsg<double> sent;
  sent.param_id = 3;
  sent.value = 0.25;
  std::uint8_t frame[fsw::kMaxFrameLen + 1];
  const std::size_t n = framer.frame_message(fsw::Apid::CmdConfig, sent, 1.5, frame, sizeof(frame));

  fsw::Deframer deframer(fsw::Direction::ToFlight);
  fsw::DeframeResult r;
  deframer.feed(frame, n, r);
  fsw::CmdConfigMsg<double> got;
  const bool packet = r.kind == fsw::DeframeResult::Kind::Packet && fsw::decode(r.packet.payload, r.packet.t_s, got);

  const bool identity = fsw::cw_stm(0.0011, 0.0).isIdentity();
  std::printf("consumer: packet %s, param %u = %g, Phi(0) identity %s\n", packet ? "ok" : "missing",
              unsigned(got.param_id), got.value, identity ? "yes" : "no");
  return packet && got.param_id == sent.param_id && got.value == sent.value && identity ? 0 : 1;
}
