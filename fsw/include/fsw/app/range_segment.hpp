// The link's range-image segment as the modal tracker's input: the one place
// where the wire format (link/apid.hpp) meets the modal estimator, so the
// estimator does not depend on the link.
// Real-time core: fixed-size, no heap, no exceptions, no I/O.
#pragma once

#include <array>
#include <cstddef>

#include "fsw/link/apid.hpp"
#include "fsw/modal/modal_tracker.hpp"

namespace fsw {

// Points of one segment, held for the tracker's segment view.
template <typename S>
using ModalSegmentPoints = std::array<ModalPoint<S>, kRangePointsPerSegment>;

// Copies the segment's valid points (at most kRangePointsPerSegment) into
// points and returns the tracker's view of the segment (pointing into points).
template <typename S>
ModalSegment<S> modal_segment_of(const RangeImageSegmentMsg<S>& m, ModalSegmentPoints<S>& points) {
  const std::size_t n = m.n_points < kRangePointsPerSegment ? std::size_t(m.n_points) : kRangePointsPerSegment;
  for (std::size_t k = 0; k < n; ++k) {
    points[k].p_m = m.points[k].p_m;
    points[k].sigma_m = m.points[k].sigma_m;
  }
  ModalSegment<S> seg;
  seg.image_id = m.image_id;
  seg.last = m.seq_flags == SeqFlags::Last || m.seq_flags == SeqFlags::Unsegmented;
  seg.points = points.data();
  seg.n_points = int(n);
  return seg;
}

}  // namespace fsw
