#include "serial_port.hpp"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace fsw::platform {

unsigned baud_constant(int baud) {
  switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    default: return 0;
  }
}

SerialPort::~SerialPort() { close(); }

bool SerialPort::open(const char* path, int baud) {
  close();
  const speed_t speed = baud_constant(baud);
  if (speed == 0) {
    error_ = "unsupported baud rate";
    return false;
  }
  fd_ = ::open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    error_ = std::strerror(errno);
    return false;
  }
  termios tio{};
  if (tcgetattr(fd_, &tio) != 0) {
    error_ = std::strerror(errno);
    close();
    return false;
  }
  cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~static_cast<tcflag_t>(CRTSCTS | CSTOPB | PARENB);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  cfsetispeed(&tio, speed);
  cfsetospeed(&tio, speed);
  if (tcsetattr(fd_, TCSANOW, &tio) != 0) {
    error_ = std::strerror(errno);
    close();
    return false;
  }
  tcflush(fd_, TCIOFLUSH);
  return true;
}

void SerialPort::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

long SerialPort::read_some(std::uint8_t* buf, std::size_t cap, int timeout_ms) {
  pollfd p{fd_, POLLIN, 0};
  const int r = ::poll(&p, 1, timeout_ms);
  if (r < 0) return errno == EINTR ? 0 : -1;
  if (r == 0) return 0;
  if (p.revents & (POLLERR | POLLNVAL)) return -1;
  const ssize_t n = ::read(fd_, buf, cap);
  if (n < 0) return (errno == EAGAIN || errno == EINTR) ? 0 : -1;
  if (n == 0 && (p.revents & POLLHUP)) return -1;  // other end closed
  return static_cast<long>(n);
}

bool SerialPort::write_all(const std::uint8_t* buf, std::size_t n, int timeout_ms) {
  std::size_t done = 0;
  while (done < n) {
    const ssize_t w = ::write(fd_, buf + done, n - done);
    if (w > 0) {
      done += static_cast<std::size_t>(w);
      continue;
    }
    if (w < 0 && errno != EAGAIN && errno != EINTR) return false;
    pollfd p{fd_, POLLOUT, 0};
    const int r = ::poll(&p, 1, timeout_ms);
    if (r < 0 && errno == EINTR) return false;  // shutting down
    if (r <= 0) return false;                   // error or timeout
  }
  return true;
}

long SerialPort::write_some(const std::uint8_t* buf, std::size_t n) {
  if (n == 0) return 0;
  const ssize_t w = ::write(fd_, buf, n);
  if (w >= 0) return static_cast<long>(w);
  if (errno == EAGAIN || errno == EINTR) return 0;
  error_ = std::strerror(errno);
  return -1;
}

bool SerialPort::wait_writable(int timeout_ms) {
  pollfd p{fd_, POLLOUT, 0};
  return ::poll(&p, 1, timeout_ms) > 0 && (p.revents & POLLOUT);
}

}  // namespace fsw::platform
