#include "ev3io/sysfs.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/statfs.h>
#include <sys/types.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace ev3io {

using ev3proto::robot::Attr;

namespace {
// Filesystem magic numbers (linux/magic.h): attributes there take each write whole.
constexpr long kSysfsMagic = 0x62656572;
constexpr long kFuseMagic = 0x65735546;

/// How an attribute is opened: `command` is write-only (0200), the read-only ones (0444) for
/// reading, the rest (0644) for both.
int access_of(Attr a) {
  switch (a) {
    case Attr::command: return O_WRONLY;
    case Attr::speed_sp:
    case Attr::position_sp:
    case Attr::time_sp:
    case Attr::stop_action:
    case Attr::polarity:
    case Attr::position:
    case Attr::mode:
    case Attr::poll_ms:
    case Attr::brightness:
    case Attr::trigger:
    case Attr::delay_on:
    case Attr::delay_off: return O_RDWR;
    default: return O_RDONLY;
  }
}
}  // namespace

int SysfsIo::open(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), flags | O_CLOEXEC, 0644);
  return fd >= 0 ? fd : -errno;
}

long SysfsIo::pread(int fd, char* buf, std::size_t n) {
  const ssize_t r = ::pread(fd, buf, n, 0);
  return r >= 0 ? static_cast<long>(r) : -errno;
}

long SysfsIo::pwrite(int fd, const char* buf, std::size_t n) {
  const ssize_t r = ::pwrite(fd, buf, n, 0);
  return r >= 0 ? static_cast<long>(r) : -errno;
}

void SysfsIo::close(int fd) { ::close(fd); }

int SysfsIo::list(const std::string& dir, std::vector<std::string>& names) {
  names.clear();
  DIR* d = ::opendir(dir.c_str());
  if (d == nullptr) return -errno;
  errno = 0;
  while (const dirent* e = ::readdir(d)) {
    if (std::strcmp(e->d_name, ".") != 0 && std::strcmp(e->d_name, "..") != 0) names.emplace_back(e->d_name);
  }
  const int err = errno;
  ::closedir(d);
  return err != 0 ? -err : 0;
}

bool SysfsIo::plain_file(int fd) {
  struct statfs s {};
  if (::fstatfs(fd, &s) != 0) return false;
  const long type = static_cast<long>(s.f_type);
  return type != kSysfsMagic && type != kFuseMagic;
}

int SysfsIo::truncate(int fd, std::size_t n) {
  return ::ftruncate(fd, static_cast<off_t>(n)) == 0 ? 0 : -errno;
}

SysfsIo& system_io() {
  static SysfsIo io;
  return io;
}

SysfsDevice::SysfsDevice(SysfsIo& io, std::string dir, bool create_missing)
    : io_(io), dir_(std::move(dir)), create_(create_missing) {}

SysfsDevice::~SysfsDevice() { close_all(); }

void SysfsDevice::close_all() {
  for (File& f : files_) {
    if (f.fd >= 0) {
      io_.close(f.fd);
      ++calls_;
    }
    f = File{};
  }
}

int SysfsDevice::fd_of(Attr a) {
  File& f = files_[static_cast<std::size_t>(a)];
  if (f.fd >= 0) return f.fd;
  int flags = access_of(a);
  if (create_ && flags != O_RDONLY) flags |= O_CREAT;
  const std::string path = dir_ + "/" + std::string(ev3proto::robot::to_string(a));
  ++calls_;
  const int fd = io_.open(path, flags);
  if (fd < 0) return fd;
  f.fd = fd;
  f.plain = io_.plain_file(fd);
  return fd;
}

AccessResult SysfsDevice::fail(Attr a, int err) {
  AccessResult r;
  r.err = err;
  // ENODEV: the driver's answer once the device is gone; ENOENT: its directory has vanished.
  r.status = err == ENODEV || err == ENOENT ? Access::gone : Access::failed;
  if (r.status == Access::gone) {
    File& f = files_[static_cast<std::size_t>(a)];
    if (f.fd >= 0) {
      io_.close(f.fd);
      ++calls_;
    }
    f = File{};
  }
  return r;
}

AccessResult SysfsDevice::read(Attr a) {
  const int fd = fd_of(a);
  if (fd < 0) return fail(a, -fd);
  ++calls_;
  const long n = io_.pread(fd, buf_, sizeof buf_);
  if (n < 0) return fail(a, static_cast<int>(-n));
  AccessResult r;
  r.text = std::string_view(buf_, static_cast<std::size_t>(n));
  return r;
}

AccessResult SysfsDevice::write(Attr a, std::string_view value) {
  int fd = fd_of(a);
  if (fd < 0) return fail(a, -fd);
  ++calls_;
  long n = io_.pwrite(fd, value.data(), value.size());
  if ((n == -ENODEV || n == -ENOENT) && create_) {
    // An LED's delay_on / delay_off go away when the trigger leaves `timer` and come back with it:
    // a descriptor held from before is stale. Open it again, once.
    fail(a, ENODEV);
    fd = fd_of(a);
    if (fd < 0) return fail(a, -fd);
    ++calls_;
    n = io_.pwrite(fd, value.data(), value.size());
  }
  if (n < 0) return fail(a, static_cast<int>(-n));
  if (static_cast<std::size_t>(n) != value.size()) return fail(a, EIO);
  const File& f = files_[static_cast<std::size_t>(a)];
  if (f.plain) {
    ++calls_;
    const int t = io_.truncate(fd, value.size());
    if (t < 0) return fail(a, -t);
  }
  return AccessResult{};
}

}  // namespace ev3io
