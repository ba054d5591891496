#include "ev3io/state_file.hpp"

#include <algorithm>

#include "ev3io/cli.hpp"

#include <ev3proto/election.hpp>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace ev3io {

bool write_state_file(const std::string& path, const std::map<std::string, std::string>& kv, std::string& err) {
  std::string doc;
  for (const auto& e : kv) doc += e.first + "=" + e.second + "\n";
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

bool read_state_file(const std::string& path, std::map<std::string, std::string>& kv, std::string& err) {
  std::vector<std::string> lines;
  if (!read_lines(path, lines, err)) return false;
  for (const std::string& l : lines) {
    const std::size_t eq = l.find('=');
    if (eq == std::string::npos || l.empty() || l[0] == '#') continue;
    kv[l.substr(0, eq)] = l.substr(eq + 1);
  }
  return true;
}

bool parse_id_list(const std::string& s, std::vector<std::uint16_t>& out) {
  out.clear();
  for (std::size_t pos = 0; pos < s.size();) {
    std::size_t comma = s.find(',', pos);
    if (comma == std::string::npos) comma = s.size();
    std::uint64_t id = 0;
    if (!to_uint(std::string_view(s).substr(pos, comma - pos), 2, 49999, id) ||
        std::find(out.begin(), out.end(), static_cast<std::uint16_t>(id)) != out.end()) {
      out.clear();
      return false;
    }
    out.push_back(static_cast<std::uint16_t>(id));
    pos = comma + 1;
    if (comma + 1 == s.size()) {  // a trailing comma
      out.clear();
      return false;
    }
  }
  return true;
}

std::string format_id_list(const std::vector<std::uint16_t>& ids) {
  std::string s;
  for (std::uint16_t id : ids) s += (s.empty() ? "" : ",") + std::to_string(id);
  return s;
}

}  // namespace ev3io

namespace ev3io {

bool read_membership(const std::map<std::string, std::string>& kv, std::uint32_t epoch, bool with_floor,
                     StoredMembership& out, std::string& err) {
  out = StoredMembership{};
  auto value = [&kv](const char* key) {
    const auto it = kv.find(key);
    return it == kv.end() ? std::string() : it->second;
  };
  const std::string members = value("members"), mepoch = value("members_epoch"), floor = value("floor");
  const std::string e = std::to_string(epoch);
  if (!parse_id_list(members, out.members) || out.members.size() > ev3proto::kMaxMembership) {
    err = "members: '" + members + "' is not a list of at most " + std::to_string(ev3proto::kMaxMembership) +
          " distinct agent ids 2..49999, comma-separated";
    return false;
  }
  std::uint64_t n = 0;
  if (!mepoch.empty() && !to_uint(mepoch, 0, epoch, n)) {
    err = "members_epoch: '" + mepoch + "' is not a number 0.." + e + " (the epoch)";
    return false;
  }
  out.members_epoch = static_cast<std::uint32_t>(n);
  if (!out.members.empty() && out.members_epoch == 0) {
    err = "members_epoch: " + std::string(mepoch.empty() ? "missing" : "0") +
          ", but members lists agents (the epoch that published them is needed)";
    return false;
  }
  if (!with_floor) return true;
  n = 0;
  if (!floor.empty() && !to_uint(floor, 0, epoch, n)) {
    err = "floor: '" + floor + "' is not a number " + std::to_string(out.members_epoch) + ".." + e +
          " (members_epoch..epoch)";
    return false;
  }
  out.floor = static_cast<std::uint32_t>(n);
  if (out.floor < out.members_epoch) {
    err = "floor: " + (floor.empty() ? std::string("missing, but members_epoch is ") : floor + " is below members_epoch ") +
          std::to_string(out.members_epoch) + " (learning a membership raises the floor to its epoch)";
    return false;
  }
  return true;
}

}  // namespace ev3io
