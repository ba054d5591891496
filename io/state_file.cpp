#include "ev3io/state_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace ev3io {

bool write_state_file(const std::string& path, std::string_view doc, std::string& err) {
  const std::string tmp = path + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    err = "cannot write " + tmp + ": " + std::strerror(errno);
    return false;
  }
  std::size_t off = 0;
  while (off < doc.size()) {
    const ssize_t n = ::write(fd, doc.data() + off, doc.size() - off);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      err = "cannot write " + tmp + ": " + std::strerror(errno);
      ::close(fd);
      return false;
    }
    off += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    err = "cannot fsync " + tmp + ": " + std::strerror(errno);
    ::close(fd);
    return false;
  }
  ::close(fd);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    err = "cannot rename " + tmp + " to " + path + ": " + std::strerror(errno);
    return false;
  }
  const std::size_t slash = path.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);  // the rename itself on stable storage
    ::close(dfd);
  }
  return true;
}

bool read_lines(const std::string& path, std::vector<std::string>& lines, std::string& err) {
  std::FILE* f = std::fopen(path.c_str(), "r");
  if (f == nullptr) {
    err = errno == ENOENT ? std::string() : "cannot read " + path + ": " + std::strerror(errno);
    return false;
  }
  char* buf = nullptr;
  std::size_t cap = 0;
  for (ssize_t n; (n = ::getline(&buf, &cap, f)) >= 0;) {
    std::string l(buf, static_cast<std::size_t>(n));
    if (!l.empty() && l.back() == '\n') l.pop_back();
    lines.push_back(std::move(l));
  }
  const bool failed = std::ferror(f) != 0;
  std::free(buf);
  std::fclose(f);
  if (failed) {
    err = "cannot read " + path;
    return false;
  }
  return true;
}

bool read_state_file(const std::string& path, std::string& text, std::string& err) {
  std::vector<std::string> lines;
  if (!read_lines(path, lines, err)) return false;
  text.clear();
  for (const std::string& l : lines) text += l + "\n";
  return true;
}

}  // namespace ev3io
