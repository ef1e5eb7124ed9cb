// POSIX serial port in raw mode (platform layer: may do I/O, not real-time
// core). Used by the flight executable; a pseudo-terminal works the same.
#pragma once

#include <cstddef>
#include <cstdint>

namespace fsw::platform {

class SerialPort {
 public:
  SerialPort() = default;
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;
  SerialPort(SerialPort&&) = delete;
  SerialPort& operator=(SerialPort&&) = delete;

  // Opens path in raw mode (8N1, no flow control, no echo, no line
  // discipline) at baud. Returns false and sets error() on failure.
  bool open(const char* path, int baud);
  void close();
  bool is_open() const { return fd_ >= 0; }

  // Waits up to timeout_ms for bytes; returns the count read (0 on timeout),
  // or -1 on a hard error (device gone).
  long read_some(std::uint8_t* buf, std::size_t cap, int timeout_ms);
  // Writes every byte, waiting for the port as needed, up to timeout_ms in
  // all; returns false on error or timeout.
  bool write_all(const std::uint8_t* buf, std::size_t n, int timeout_ms);
  // Writes what the port takes now, without waiting: the count written (0
  // when the port is full), or -1 on a hard error (error() says which).
  long write_some(const std::uint8_t* buf, std::size_t n);
  // Waits up to timeout_ms until the port takes bytes; false on timeout.
  bool wait_writable(int timeout_ms);

  const char* error() const { return error_; }

 private:
  int fd_ = -1;
  const char* error_ = "";
};

// termios speed constant for a baud rate, or 0 if unsupported.
unsigned baud_constant(int baud);

}  // namespace fsw::platform
