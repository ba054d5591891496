// The device layer's system calls with faults injected (the seam of io/ev3io/sysfs.hpp): devices
// unplugged (their files answer ENODEV, their directories leave the listings, opening below them
// is ENOENT), an errno for every read or write of a file, and counts of the calls.
#pragma once

#include <algorithm>
#include <cerrno>
#include <map>
#include <string>
#include <vector>

#include "ev3io/sysfs.hpp"

namespace ev3test {

/// The real system calls, with faults: devices unplugged (their files answer ENODEV, their
/// directories vanish from listings, opening below them is ENOENT), errors for one file, counts.
class FaultIo : public ev3io::SysfsIo {
 public:
  std::vector<std::string> unplugged;     ///< path prefixes of unplugged devices
  std::map<std::string, int> write_error; ///< path suffix -> errno of every pwrite to it
  std::map<std::string, int> read_error;  ///< path suffix -> errno of every pread of it
  bool sysfs = false;                     ///< say the files are sysfs (no truncate after writes)
  std::size_t opens = 0, preads = 0, pwrites = 0, truncates = 0;

  int open(const std::string& path, int flags) override {
    ++opens;
    if (below_unplugged(path)) return -ENOENT;
    const int fd = SysfsIo::open(path, flags);
    if (fd >= 0) paths_[fd] = path;
    return fd;
  }
  long pread(int fd, char* buf, std::size_t n) override {
    ++preads;
    if (const int e = fault(fd, read_error)) return -e;
    return SysfsIo::pread(fd, buf, n);
  }
  long pwrite(int fd, const char* buf, std::size_t n) override {
    ++pwrites;
    if (const int e = fault(fd, write_error)) return -e;
    return SysfsIo::pwrite(fd, buf, n);
  }
  void close(int fd) override {
    paths_.erase(fd);
    SysfsIo::close(fd);
  }
  int list(const std::string& dir, std::vector<std::string>& names) override {
    const int r = SysfsIo::list(dir, names);
    names.erase(std::remove_if(names.begin(), names.end(), [&](const std::string& n) { return below_unplugged(dir + "/" + n); }),
                names.end());
    return r;
  }
  bool plain_file(int fd) override { return !sysfs && SysfsIo::plain_file(fd); }
  int truncate(int fd, std::size_t n) override {
    ++truncates;
    return SysfsIo::truncate(fd, n);
  }
  std::size_t calls() const { return opens + preads + pwrites + truncates; }

 private:
  bool below_unplugged(const std::string& path) const {
    for (const auto& u : unplugged)
      if (path.rfind(u, 0) == 0) return true;
    return false;
  }
  int fault(int fd, const std::map<std::string, int>& errors) const {
    auto p = paths_.find(fd);
    if (p == paths_.end()) return 0;
    if (below_unplugged(p->second)) return ENODEV;
    for (const auto& [suffix, e] : errors)
      if (p->second.size() >= suffix.size() && p->second.compare(p->second.size() - suffix.size(), suffix.size(), suffix) == 0)
        return e;
    return 0;
  }
  std::map<int, std::string> paths_;
};

}  // namespace ev3test
