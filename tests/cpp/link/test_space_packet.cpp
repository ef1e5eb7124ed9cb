// CCSDS primary header pack/unpack, the time tag and the APID table.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <type_traits>

#include "fsw/link/apid.hpp"
#include "fsw/link/space_packet.hpp"
#include "tolerances.hpp"

using namespace fsw;

TEST(SpacePacket, PacksKnownHeaderBytes) {
  // TC, sec header, APID 0x011, unsegmented, count 5, 72 + 8 bytes of data field.
  PrimaryHeader h;
  h.type = PacketType::Telecommand;
  h.apid = 0x011;
  h.seq_flags = SeqFlags::Unsegmented;
  h.seq_count = 5;
  h.data_length = 79;
  std::array<std::uint8_t, 6> b{};
  pack_primary_header(h, b.data());
  EXPECT_EQ(b, (std::array<std::uint8_t, 6>{0x18, 0x11, 0xC0, 0x05, 0x00, 0x4F}));
}

TEST(SpacePacket, RoundTripEveryFieldExtreme) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 2000; ++trial) {
    PrimaryHeader h;
    h.version = static_cast<std::uint8_t>(rng() % 8);
    h.type = static_cast<PacketType>(rng() % 2);
    h.sec_header = rng() % 2;
    h.apid = static_cast<std::uint16_t>(rng() % 2048);
    h.seq_flags = static_cast<SeqFlags>(rng() % 4);
    h.seq_count = static_cast<std::uint16_t>(rng() % 16384);
    h.data_length = static_cast<std::uint16_t>(rng());
    std::array<std::uint8_t, 6> b{};
    pack_primary_header(h, b.data());
    const PrimaryHeader u = unpack_primary_header(b.data());
    ASSERT_EQ(u.version, h.version);
    ASSERT_EQ(u.type, h.type);
    ASSERT_EQ(u.sec_header, h.sec_header);
    ASSERT_EQ(u.apid, h.apid);
    ASSERT_EQ(u.seq_flags, h.seq_flags);
    ASSERT_EQ(u.seq_count, h.seq_count);
    ASSERT_EQ(u.data_length, h.data_length);
  }
}

TEST(SpacePacket, OversizedFieldsAreMaskedNotSpilled) {
  PrimaryHeader h;
  h.apid = 0xFFFF;
  h.seq_count = 0xFFFF;
  std::array<std::uint8_t, 6> b{};
  pack_primary_header(h, b.data());
  const PrimaryHeader u = unpack_primary_header(b.data());
  EXPECT_EQ(u.apid, 0x7FF);
  EXPECT_EQ(u.seq_count, 0x3FFF);
  EXPECT_EQ(u.version, 0);
  EXPECT_EQ(u.type, PacketType::Telemetry);
  EXPECT_EQ(u.seq_flags, SeqFlags::Unsegmented);
}

TEST(SpacePacket, DataLengthIsBytesAfterPrimaryHeaderMinusOne) {
  std::uint16_t f = 0;
  ASSERT_TRUE(data_length_for(6 + 8 + 48, f));
  EXPECT_EQ(f, 55);
  EXPECT_EQ(packet_length_from_field(f), 62u);
  EXPECT_FALSE(data_length_for(6, f));
  EXPECT_TRUE(data_length_for(6 + 65536, f));
  EXPECT_EQ(f, 0xFFFF);
  EXPECT_FALSE(data_length_for(6 + 65537, f));
}

TEST(SpacePacket, LengthField0xFFFFDoesNotWrap) { EXPECT_EQ(packet_length_from_field(0xFFFF), 65542u); }

TEST(SpacePacket, TimeTagIsLittleEndianDouble) {
  std::array<std::uint8_t, 8> b{};
  pack_time_tag(1.0, b.data());
  EXPECT_EQ(b, (std::array<std::uint8_t, 8>{0, 0, 0, 0, 0, 0, 0xF0, 0x3F}));
  const double t = 12345.678901234567;
  pack_time_tag(t, b.data());
  EXPECT_EQ(unpack_time_tag(b.data()), t);  // bit exact
}

TEST(SpacePacket, LittleEndianIntegers) {
  std::array<std::uint8_t, 8> b{};
  put_u32le(b.data(), 0x11223344u);
  EXPECT_EQ(b[0], 0x44);
  EXPECT_EQ(get_u32le(b.data()), 0x11223344u);
  put_u16le(b.data(), 0xBEEF);
  EXPECT_EQ(get_u16le(b.data()), 0xBEEF);
}

TEST(ApidTable, EveryApidKnownAndUniqueAndBelowIdle) {
  for (const auto& r : kApidTable) {
    EXPECT_EQ(apid_info(static_cast<std::uint16_t>(r.apid)), &r);
    EXPECT_LT(static_cast<std::uint16_t>(r.apid), kIdleApid);
  }
  EXPECT_EQ(apid_info(0x7FF), nullptr);
  EXPECT_EQ(apid_info(0x000), nullptr);
}

TEST(ApidTable, PayloadLengthsAsDocumented) {
  EXPECT_EQ(apid_info(0x010)->payload_len, 48);
  EXPECT_EQ(apid_info(0x011)->payload_len, 72);
  EXPECT_EQ(apid_info(0x012)->payload_len, 16);
  EXPECT_EQ(apid_info(0x013)->payload_len, 780);
  EXPECT_EQ(apid_info(0x020)->payload_len, 112);
  EXPECT_EQ(apid_info(0x021)->payload_len, 16);
  EXPECT_EQ(apid_info(0x040)->payload_len, 80);
  EXPECT_EQ(apid_info(0x041)->payload_len, 128);
  EXPECT_EQ(apid_info(0x042)->payload_len, 72);
  EXPECT_EQ(apid_info(0x043)->payload_len, 104);
  EXPECT_EQ(apid_info(0x044)->payload_len, 128);
  EXPECT_EQ(apid_info(0x045)->payload_len, 40);
  EXPECT_EQ(apid_info(0x022)->payload_len, 32);
  EXPECT_EQ(apid_info(0x023)->payload_len, 24);
  EXPECT_EQ(apid_info(0x047)->payload_len, 40);
  EXPECT_EQ(apid_info(0x048)->payload_len, 88);
  EXPECT_EQ(kMaxPayloadLen, 780u);
  EXPECT_TRUE(apid_info(0x013)->segmentable);
}

// Typed codecs in float and double: encode then decode gives the values back
// (exactly for double; to float rounding for float).
template <typename S>
class PayloadCodec : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(PayloadCodec, Scalars);

TYPED_TEST(PayloadCodec, LedPoseRoundTrip) {
  using S = TypeParam;
  LedPoseMsg<S> m;
  m.r_hill_m << S(0.5), S(-0.25), S(0.125);
  m.q_hb = normalized(Quat<S>(S(0.9), S(0.1), S(-0.2), S(0.3)));
  m.r_sigma_m = S(0.02);
  m.att_sigma_rad = S(0.01);
  std::array<std::uint8_t, 72> p{};
  encode(m, p.data());
  LedPoseMsg<S> u;
  ASSERT_TRUE(decode(p.data(), 3.5, u));
  EXPECT_EQ(u.t_s, S(3.5));
  EXPECT_EQ(u.r_hill_m, m.r_hill_m);
  EXPECT_EQ(to_wxyz(u.q_hb), to_wxyz(m.q_hb));
  EXPECT_EQ(u.r_sigma_m, m.r_sigma_m);
  // The quaternion is scalar-first on the wire.
  EXPECT_EQ(get_f64le(p.data() + 24), static_cast<double>(m.q_hb.w()));
}

TYPED_TEST(PayloadCodec, RangeSegmentRoundTrip) {
  using S = TypeParam;
  RangeImageSegmentMsg<S> m;
  m.image_id = 77;
  m.points_total = 50;
  m.first_point = 24;
  m.n_points = 24;
  for (std::size_t i = 0; i < kRangePointsPerSegment; ++i) {
    m.points[i].p_m << S(i), S(2 * i), S(-1);
    m.points[i].sigma_m = S(0.03);
  }
  std::array<std::uint8_t, 780> p{};
  encode(m, p.data());
  EXPECT_TRUE(payload_fields_valid(Apid::RangeImageSegment, SeqFlags::Continuation, p.data()));
  EXPECT_FALSE(payload_fields_valid(Apid::RangeImageSegment, SeqFlags::First, p.data()));
  RangeImageSegmentMsg<S> u;
  ASSERT_TRUE(decode(p.data(), 1.0, SeqFlags::Continuation, u));
  EXPECT_EQ(u.image_id, 77u);
  EXPECT_EQ(u.first_point, 24);
  EXPECT_EQ(u.points[23].p_m, m.points[23].p_m);
}

TYPED_TEST(PayloadCodec, DoubleThatOverflowsTheScalarIsRefused) {
  using S = TypeParam;
  ImuSampleMsg<double> m;
  m.accel_b_mps2 << 1e300, 0, 0;
  std::array<std::uint8_t, 48> p{};
  encode(m, p.data());
  ImuSampleMsg<S> u;
  // 1e300 is finite as a double and infinite as a float.
  EXPECT_EQ(decode(p.data(), 0.0, u), (std::is_same<S, double>::value));
}

TYPED_TEST(PayloadCodec, EstimateInnovationLearnerHousekeepingRoundTrip) {
  using S = TypeParam;
  TmEstimateMsg<S> e;
  e.r_hill_m << S(1), S(2), S(3);
  e.v_hill_mps << S(-0.5), S(0.25), S(0);
  std::array<std::uint8_t, 128> p{};
  encode(e, p.data());
  TmEstimateMsg<S> eu;
  ASSERT_TRUE(decode(p.data(), 0.0, eu));
  EXPECT_EQ(eu.v_hill_mps, e.v_hill_mps);

  TmInnovationMsg<S> in;
  in.status = 1;
  in.meas_dim = 6;
  in.step_index = 99;
  in.innovation << S(1), S(2), S(3), S(4), S(5), S(6);
  in.nis = S(7.5);
  in.log_likelihood = S(-3.25);
  encode(in, p.data());
  TmInnovationMsg<S> iu;
  ASSERT_TRUE(decode(p.data(), 0.0, iu));
  EXPECT_EQ(iu.step_index, 99u);
  EXPECT_EQ(iu.innovation, in.innovation);
  EXPECT_EQ(iu.log_likelihood, in.log_likelihood);

  TmLearnerMsg<S> l;
  l.n_samples = 30;
  l.variance.setConstant(S(0.5));
  encode(l, p.data());
  TmLearnerMsg<S> lu;
  ASSERT_TRUE(decode(p.data(), 0.0, lu));
  EXPECT_EQ(lu.n_samples, 30u);
  EXPECT_EQ(lu.variance, l.variance);

  TmHousekeepingMsg<S> hk;
  hk.uptime_s = S(12);
  hk.cycle_count = 120;
  hk.tx_packets = 7;
  hk.tx_dropped = 0x01020304u;
  encode(hk, p.data());
  EXPECT_EQ(get_u32le(p.data() + 36), 0x01020304u);  // docs/LINK.md: offset 36
  TmHousekeepingMsg<S> hu;
  ASSERT_TRUE(decode(p.data(), 0.0, hu));
  EXPECT_EQ(hu.cycle_count, 120u);
  EXPECT_EQ(hu.tx_packets, 7u);
  EXPECT_EQ(hu.tx_dropped, 0x01020304u);
  EXPECT_EQ(hu.uptime_s, S(12));
}

TEST(PayloadCodecCounters, LinkCountersRoundTrip) {
  TmLinkCountersMsg m;
  m.packets_accepted = 10;
  m.rejected[4] = 3;
  std::array<std::uint8_t, 128> p{};
  encode(m, p.data());
  TmLinkCountersMsg u;
  ASSERT_TRUE(decode(p.data(), 2.0, u));
  EXPECT_EQ(u.packets_accepted, 10u);
  EXPECT_EQ(u.rejected[4], 3u);
}

// The valve plan's messages (times in double in both builds): every field
// back exactly, at its documented offset.
TEST(PlanCodec, PlanEntryRoundTripAndLayout) {
  CmdPlanEntryMsg m;
  m.plan_id = 0xA1B2C3D4u;
  m.entry_index = 17;
  m.entry_count = 128;
  m.valve = 6;
  m.t_open_s = 12.3;
  m.t_close_s = 15.3;
  std::array<std::uint8_t, 32> p{};
  p.fill(0xEE);
  encode(m, p.data());
  EXPECT_EQ(get_u32le(p.data()), 0xA1B2C3D4u);
  EXPECT_EQ(get_u16le(p.data() + 4), 17);
  EXPECT_EQ(get_u16le(p.data() + 6), 128);
  EXPECT_EQ(p[8], 6);
  for (int i = 9; i < 16; ++i) EXPECT_EQ(p[i], 0) << i;  // reserved
  EXPECT_EQ(get_f64le(p.data() + 16), 12.3);
  CmdPlanEntryMsg back;
  ASSERT_TRUE(decode(p.data(), 4.5, back));
  EXPECT_EQ(back.t_s, 4.5);
  EXPECT_EQ(back.plan_id, m.plan_id);
  EXPECT_EQ(back.entry_index, m.entry_index);
  EXPECT_EQ(back.entry_count, m.entry_count);
  EXPECT_EQ(back.valve, m.valve);
  EXPECT_EQ(back.t_open_s, m.t_open_s);
  EXPECT_EQ(back.t_close_s, m.t_close_s);
}

TEST(PlanCodec, PlanCommandRoundTripAndLayout) {
  CmdPlanMsg m;
  m.action = static_cast<std::uint32_t>(PlanAction::Load);
  m.plan_id = 42;
  m.entry_count = 26;
  m.duration_s = 119.5;
  std::array<std::uint8_t, 24> p{};
  p.fill(0xEE);
  encode(m, p.data());
  EXPECT_EQ(get_u32le(p.data() + 12), 0u);  // reserved
  EXPECT_EQ(get_f64le(p.data() + 16), 119.5);
  CmdPlanMsg back;
  ASSERT_TRUE(decode(p.data(), 1.0, back));
  EXPECT_EQ(back.action, m.action);
  EXPECT_EQ(back.plan_id, 42u);
  EXPECT_EQ(back.entry_count, 26u);
  EXPECT_EQ(back.duration_s, 119.5);
}

TEST(PlanCodec, PlanStatusAndValvesRoundTrip) {
  TmPlanStatusMsg s;
  s.plan_id = 3;
  s.state = 2;
  s.action = 1;
  s.verdict = 7;
  s.entry_count = 5;
  s.entries_received = 4;
  s.plans_loaded = 9;
  s.commands_refused = 11;
  s.duration_s = 60.5;
  s.total_on_time_s = 7.25;
  std::array<std::uint8_t, 40> ps{};
  encode(s, ps.data());
  TmPlanStatusMsg sb;
  ASSERT_TRUE(decode(ps.data(), 2.0, sb));
  EXPECT_EQ(sb.plan_id, 3u);
  EXPECT_EQ(sb.state, 2);
  EXPECT_EQ(sb.action, 1);
  EXPECT_EQ(sb.verdict, 7);
  EXPECT_EQ(sb.entry_count, 5u);
  EXPECT_EQ(sb.entries_received, 4u);
  EXPECT_EQ(sb.plans_loaded, 9u);
  EXPECT_EQ(sb.commands_refused, 11u);
  EXPECT_EQ(sb.duration_s, 60.5);
  EXPECT_EQ(sb.total_on_time_s, 7.25);
  EXPECT_TRUE(payload_fields_valid(Apid::TmPlanStatus, SeqFlags::Unsegmented, ps.data()));
  ps[6] = kPlanVerdictMax + 1;
  EXPECT_FALSE(payload_fields_valid(Apid::TmPlanStatus, SeqFlags::Unsegmented, ps.data()));

  TmPlanValvesMsg v;
  v.plan_id = 3;
  v.valve_mask = 0x84;
  v.state = 2;
  v.interval_s = 0.1;
  v.plan_time_s = 2.3;
  v.on_time_s[2] = 0.1;
  v.on_time_s[7] = 0.05;
  std::array<std::uint8_t, 88> pv{};
  encode(v, pv.data());
  EXPECT_EQ(get_f64le(pv.data() + 24 + 8 * 7), 0.05);
  TmPlanValvesMsg vb;
  ASSERT_TRUE(decode(pv.data(), 3.3, vb));
  EXPECT_EQ(vb.valve_mask, 0x84);
  EXPECT_EQ(vb.state, 2);
  EXPECT_EQ(vb.interval_s, 0.1);
  EXPECT_EQ(vb.plan_time_s, 2.3);
  EXPECT_EQ(vb.on_time_s, v.on_time_s);
  pv[5] = kPlanStateMax + 1;
  EXPECT_FALSE(payload_fields_valid(Apid::TmPlanValves, SeqFlags::Unsegmented, pv.data()));
}
