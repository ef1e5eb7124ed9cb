// The link's range-image segment as the modal tracker's input
// (app/range_segment.hpp): points copied, count clamped to the segment's
// capacity, the image closed by its last or only segment.
#include <gtest/gtest.h>

#include "fsw/app/range_segment.hpp"

using namespace fsw;

namespace {

RangeImageSegmentMsg<double> segment(std::uint16_t n, SeqFlags flags) {
  RangeImageSegmentMsg<double> m;
  m.image_id = 7;
  m.seq_flags = flags;
  m.n_points = n;
  for (std::size_t k = 0; k < kRangePointsPerSegment; ++k) {
    m.points[k].p_m = Vec3<double>(double(k), -double(k), 0.5 * double(k));
    m.points[k].sigma_m = 0.01 * double(k);
  }
  return m;
}

}  // namespace

TEST(RangeSegment, CopiesThePointsAndTheImage) {
  const auto m = segment(5, SeqFlags::First);
  ModalSegmentPoints<double> points;
  const ModalSegment<double> s = modal_segment_of(m, points);
  EXPECT_EQ(s.image_id, 7u);
  EXPECT_FALSE(s.last);
  ASSERT_EQ(s.n_points, 5);
  EXPECT_EQ(s.points, points.data());
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(s.points[k].p_m, m.points[std::size_t(k)].p_m);
    EXPECT_EQ(s.points[k].sigma_m, m.points[std::size_t(k)].sigma_m);
  }
}

TEST(RangeSegment, LastOrOnlySegmentClosesTheImage) {
  ModalSegmentPoints<double> points;
  EXPECT_FALSE(modal_segment_of(segment(1, SeqFlags::Continuation), points).last);
  EXPECT_TRUE(modal_segment_of(segment(1, SeqFlags::Last), points).last);
  EXPECT_TRUE(modal_segment_of(segment(1, SeqFlags::Unsegmented), points).last);
}

TEST(RangeSegment, CountClampedToTheSegmentCapacity) {
  ModalSegmentPoints<float> points;
  RangeImageSegmentMsg<float> m;
  m.n_points = std::uint16_t(kRangePointsPerSegment + 3);
  EXPECT_EQ(modal_segment_of(m, points).n_points, int(kRangePointsPerSegment));
}
