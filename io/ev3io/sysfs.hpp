/// @file sysfs.hpp
/// @brief sysfs attribute files held open: one directory of a device (a motor, a sensor, an LED,
///        the battery) whose attribute files are opened once, on first use, and then read with one
///        pread and written with one pwrite each (ev3dev users measured 10-15 ms per access through
///        a stream opened per access, under 0.4 ms with held descriptors).
///
/// The system calls go through SysfsIo, a small interface the tests replace to inject the errors a
/// plain file cannot give (ENODEV after an unplug, EBUSY from `position`). The layer uses only
/// open / pread / pwrite / close / readdir / fstatfs (and ftruncate on plain files, see below):
/// nothing specific to FUSE or to a kernel version.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include <ev3proto/robot/device.hpp>

namespace ev3io {

/// The system calls of the device layer. Each returns -errno on failure (never sets errno).
class SysfsIo {
 public:
  virtual ~SysfsIo() = default;
  /// open(2) with @p flags (O_CLOEXEC is added); a descriptor or -errno.
  virtual int open(const std::string& path, int flags);
  /// pread(2) at offset 0: bytes read or -errno.
  virtual long pread(int fd, char* buf, std::size_t n);
  /// pwrite(2) at offset 0: bytes written or -errno.
  virtual long pwrite(int fd, const char* buf, std::size_t n);
  virtual void close(int fd);
  /// The names in directory @p dir (without . and ..): 0 or -errno.
  virtual int list(const std::string& dir, std::vector<std::string>& names);
  /// True when @p fd is a file on an ordinary filesystem (not sysfs, not FUSE): a test tree or a
  /// copy. Such files keep old bytes past a shorter pwrite, so writes there are followed by
  /// ftruncate (sysfs and FUSE attributes take each write whole: one pwrite, nothing else).
  virtual bool plain_file(int fd);
  /// ftruncate(2): 0 or -errno.
  virtual int truncate(int fd, std::size_t n);
};

/// The real system calls.
SysfsIo& system_io();

/// What an access gave.
enum class Access {
  ok,      ///< done; a read's text is in AccessResult::text
  gone,    ///< ENODEV, or the file / directory is no longer there: the device is unplugged
  failed,  ///< any other error (err): EBUSY, EINVAL, EIO, ETIMEDOUT, EOPNOTSUPP ...
};

struct AccessResult {
  Access status = Access::ok;
  int err = 0;                ///< errno when not ok
  std::string_view text;      ///< read: the bytes read (valid until the next read of the device)
};

/// One device directory with its attribute files held open.
class SysfsDevice {
 public:
  /// @p dir: the device's directory (ROOT/class/tacho-motor/motor0). @p create_missing: open
  /// files for writing with O_CREAT (the LEDs: their delay_on / delay_off exist only while the
  /// trigger is `timer`, and a plain-file tree may lack them).
  SysfsDevice(SysfsIo& io, std::string dir, bool create_missing = false);
  ~SysfsDevice();
  SysfsDevice(const SysfsDevice&) = delete;
  SysfsDevice& operator=(const SysfsDevice&) = delete;

  /// Reads attribute @p a (one pread; the file is opened on first use).
  AccessResult read(ev3proto::robot::Attr a);
  /// Writes @p value to attribute @p a (one pwrite).
  AccessResult write(ev3proto::robot::Attr a, std::string_view value);
  /// Closes every file (the device is gone); the next access opens them again.
  void close_all();
  const std::string& dir() const noexcept { return dir_; }
  /// System calls made so far (open, pread, pwrite, close, truncate): the benchmark counts them.
  std::size_t calls() const noexcept { return calls_; }

 private:
  struct File {
    int fd = -1;
    bool plain = false;
  };
  /// The open descriptor of @p a, or -errno.
  int fd_of(ev3proto::robot::Attr a);
  AccessResult fail(ev3proto::robot::Attr a, int err);

  SysfsIo& io_;
  std::string dir_;
  bool create_;
  std::array<File, ev3proto::robot::kAttrCount> files_{};
  char buf_[256];
  std::size_t calls_ = 0;
};

}  // namespace ev3io
