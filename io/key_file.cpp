#include "ev3io/key_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace ev3io {

std::string load_key_file(const std::string& path, ev3proto::auth::Key& key) {
  if (sodium_init() < 0) return path + ": libsodium cannot start";
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return path + ": cannot be read: " + std::strerror(errno);
  struct stat st{};
  if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return path + ": not a regular file";
  }
  if ((st.st_mode & 077) != 0) {
    ::close(fd);
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    return path + ": readable by group or others (mode " + mode + "): chmod 600 it";
  }
  char buf[80];
  std::size_t n = 0;
  for (ssize_t r; n < sizeof buf && (r = ::read(fd, buf + n, sizeof buf - n)) != 0;) {
    if (r < 0) {
      if (errno == EINTR) continue;
      ::close(fd);
      return path + ": cannot be read: " + std::strerror(errno);
    }
    n += static_cast<std::size_t>(r);
  }
  ::close(fd);
  const char* why = ev3proto::auth::Key::parse(std::string_view(buf, n), key);
  sodium_memzero(buf, sizeof buf);
  if (why != nullptr) return path + ": " + why;
  return {};
}

}  // namespace ev3io
