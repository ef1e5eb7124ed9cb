// Consistent Overhead Byte Stuffing (COBS, Cheshire & Baker 1999): removes
// every 0x00 from a packet so that 0x00 can end each frame on the serial link.
// Encoding matches the PyPI `cobs` package byte for byte. No heap: the
// encoder writes into a caller buffer with a bound, the decoder likewise, and
// the frame accumulator has a fixed capacity.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace fsw {

// Worst-case encoded size (without the trailing 0x00) for n input bytes.
constexpr std::size_t cobs_max_encoded_size(std::size_t n) { return n + n / 254 + 1; }

// Encodes n bytes into out (capacity cap). Returns the encoded length, or 0
// if cap is too small (a valid encoding is never empty).
inline std::size_t cobs_encode(const std::uint8_t* in, std::size_t n, std::uint8_t* out, std::size_t cap) {
  if (cap < cobs_max_encoded_size(n)) return 0;
  std::size_t o = 1;
  std::size_t code_idx = 0;
  std::uint8_t code = 1;
  bool open = true;  // a block awaits its code byte
  for (std::size_t i = 0; i < n; ++i) {
    if (in[i] == 0) {
      out[code_idx] = code;
      code_idx = o++;
      code = 1;
    } else {
      out[o++] = in[i];
      ++code;
      if (code == 0xFF) {
        out[code_idx] = code;
        // A full block at the very end needs no empty block after it.
        if (i + 1 < n) {
          code_idx = o++;
          code = 1;
        } else {
          open = false;
        }
      }
    }
  }
  if (open) out[code_idx] = code;
  return o;
}

enum class CobsStatus : std::uint8_t {
  Ok = 0,
  ZeroInFrame,  // a 0x00 inside a frame (only possible if the caller did not split on zero)
  CodePastEnd,  // a code byte announces more bytes than the frame holds
  Overflow,     // the decoded bytes do not fit the output buffer
};

// Decodes one frame (without its trailing 0x00). Every loop is bounded by n.
inline CobsStatus cobs_decode(const std::uint8_t* in, std::size_t n, std::uint8_t* out, std::size_t cap,
                              std::size_t& out_len) {
  out_len = 0;
  std::size_t i = 0;
  std::size_t o = 0;
  while (i < n) {
    const std::uint8_t code = in[i++];
    if (code == 0) return CobsStatus::ZeroInFrame;
    const std::size_t run = static_cast<std::size_t>(code) - 1;
    if (run > n - i) return CobsStatus::CodePastEnd;
    if (run > cap - o) return CobsStatus::Overflow;
    // A run is copied whole (memchr and memcpy work a vector at a time).
    if (std::memchr(in + i, 0, run) != nullptr) return CobsStatus::ZeroInFrame;
    std::memcpy(out + o, in + i, run);
    i += run;
    o += run;
    if (code != 0xFF && i < n) {
      if (o >= cap) return CobsStatus::Overflow;
      out[o++] = 0;
    }
  }
  out_len = o;
  return CobsStatus::Ok;
}

// Streaming frame accumulator: bytes go in one at a time; a 0x00 ends a frame.
// A frame longer than Capacity is reported once as a runaway and the bytes up
// to the next 0x00 are dropped (that 0x00 resynchronises).
template <std::size_t Capacity>
class CobsAccumulator {
 public:
  enum class Event : std::uint8_t {
    None = 0,    // byte stored (or dropped while resynchronising)
    Frame,       // a 0x00 closed a non-empty frame: frame()/size() are valid
    EmptyFrame,  // a 0x00 closed an empty frame
    Runaway,     // the frame passed Capacity bytes without a 0x00
  };

  Event push(std::uint8_t b) {
    if (b == 0) {
      if (discarding_) {
        discarding_ = false;
        len_ = 0;
        return Event::None;
      }
      frame_len_ = len_;
      len_ = 0;
      return frame_len_ == 0 ? Event::EmptyFrame : Event::Frame;
    }
    if (discarding_) return Event::None;
    if (len_ >= Capacity) {
      discarding_ = true;
      len_ = 0;
      return Event::Runaway;
    }
    buf_[len_++] = b;
    return Event::None;
  }

  // push() over data[0, n) up to and including the byte that raises an event
  // (ev; Event::None if none did), in runs between zeros rather than byte by
  // byte. Returns the number of bytes consumed.
  std::size_t push_bytes(const std::uint8_t* data, std::size_t n, Event& ev) {
    ev = Event::None;
    std::size_t i = 0;
    while (i < n) {
      const void* z = std::memchr(data + i, 0, n - i);
      const std::size_t run = z ? static_cast<std::size_t>(static_cast<const std::uint8_t*>(z) - data) - i : n - i;
      if (!discarding_) {
        const std::size_t room = Capacity - len_;
        if (run > room) {  // the byte after the room is the runaway
          std::memcpy(buf_.data() + len_, data + i, room);
          len_ = Capacity;
          ev = push(data[i + room]);  // Runaway, discarding from here
          return i + room + 1;
        }
        std::memcpy(buf_.data() + len_, data + i, run);
        len_ += run;
      }
      i += run;
      if (i == n) return n;
      ev = push(0);  // the 0x00 at i
      ++i;
      if (ev != Event::None) return i;
    }
    return n;
  }

  // The last completed frame (valid until the next push of a byte).
  const std::uint8_t* frame() const { return buf_.data(); }
  std::size_t size() const { return frame_len_; }
  // Bytes of the frame in progress.
  std::size_t pending() const { return len_; }
  bool discarding() const { return discarding_; }
  void reset() {
    len_ = 0;
    frame_len_ = 0;
    discarding_ = false;
  }
  static constexpr std::size_t capacity() { return Capacity; }

 private:
  std::array<std::uint8_t, Capacity> buf_{};
  std::size_t len_ = 0;
  std::size_t frame_len_ = 0;
  bool discarding_ = false;
};

}  // namespace fsw
