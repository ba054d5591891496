#include "ev3io/line_server.hpp"

#include <fcntl.h>
#include <grp.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace ev3io {

namespace {

std::string sys_error(const std::string& what, const std::string& path) {
  return what + " " + path + ": " + std::strerror(errno);
}

bool fill_address(const std::string& path, sockaddr_un& a) {
  a = sockaddr_un{};
  a.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof a.sun_path) return false;
  std::memcpy(a.sun_path, path.data(), path.size());
  return true;
}

}  // namespace

LineServer::~LineServer() { close(); }

std::string LineServer::open(const std::string& path, const std::string& group) {
  sockaddr_un a;
  if (!fill_address(path, a))
    return "bad value for --control: " + (path.empty() ? std::string("empty path")
                                                       : path + " is longer than a socket path may be (" +
                                                             std::to_string(sizeof a.sun_path - 1) + " bytes)");
  gid_t gid = static_cast<gid_t>(-1);
  if (!group.empty()) {
    const struct group* g = getgrnam(group.c_str());
    if (g == nullptr) return "bad value for --control-group: no group " + group;
    gid = g->gr_gid;
  }
  struct stat st {};
  if (lstat(path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) return "--control " + path + ": the file exists and is not a socket";
    // Stale only when nobody listens (ECONNREFUSED); a socket we may not connect to is not ours.
    const int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (probe < 0) return sys_error("--control: socket() for", path);
    const int rc = connect(probe, reinterpret_cast<const sockaddr*>(&a), sizeof a);
    const int why = errno;
    ::close(probe);
    if (rc == 0 || why == EAGAIN || why == EINPROGRESS)
      return "--control " + path + ": another program is listening on it";
    if (why != ECONNREFUSED) {
      errno = why;
      return sys_error("--control: cannot tell whether a program listens on", path);
    }
    if (unlink(path.c_str()) != 0) return sys_error("--control: cannot remove the stale socket", path);
  }
  fd_ = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) return sys_error("--control: socket() for", path);
  const mode_t old = umask(0177);  // created 0600: no moment at which others may connect
  const int rc = bind(fd_, reinterpret_cast<const sockaddr*>(&a), sizeof a);
  umask(old);
  if (rc != 0 || listen(fd_, 16) != 0) {
    std::string e = sys_error("--control: cannot listen on", path);
    ::close(fd_);
    fd_ = -1;
    return e;
  }
  path_ = path;
  if (!group.empty() && (chown(path.c_str(), static_cast<uid_t>(-1), gid) != 0 || chmod(path.c_str(), 0660) != 0)) {
    std::string e = sys_error("--control-group " + group + ": cannot give the group", path);
    close();
    return e;
  }
  return {};
}

void LineServer::close() {
  while (!conns_.empty()) drop(conns_.size() - 1);
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
    unlink(path_.c_str());
  }
}

std::size_t LineServer::fds(pollfd* out) const {
  if (fd_ < 0) return 0;
  std::size_t n = 0;
  out[n++] = pollfd{fd_, POLLIN, 0};
  for (const Conn& c : conns_)
    out[n++] = pollfd{c.fd, static_cast<short>((c.eof ? 0 : POLLIN) | (c.out.empty() ? 0 : POLLOUT)), 0};
  return n;
}

void LineServer::serve(const pollfd* p, std::size_t n, const std::function<void(Client, const std::string&)>& on_line,
                       const std::function<std::string()>& too_long) {
  if (fd_ < 0 || n == 0) return;
  // The connections first (the descriptors polled were theirs), then new ones.
  for (std::size_t k = 1; k < n; ++k) {
    std::size_t i = 0;
    while (i < conns_.size() && conns_[i].fd != p[k].fd) ++i;
    if (i == conns_.size() || p[k].revents == 0) continue;
    if (p[k].revents & POLLOUT) flush(conns_[i]);
    if (reap(i)) continue;
    if (conns_[i].eof || !(p[k].revents & (POLLIN | POLLHUP | POLLERR))) continue;
    char buf[4096];
    const ssize_t got = read(conns_[i].fd, buf, sizeof buf);
    if (got < 0 && (errno == EAGAIN || errno == EINTR)) continue;
    if (got < 0) {
      drop(i);
      continue;
    }
    const Client id = conns_[i].id;
    if (got == 0) {
      // The client closed its side: a last line without its newline counts, then the answers owed.
      conns_[i].eof = true;
      if (!conns_[i].in.empty() && !conns_[i].skipping) conns_[i].in += '\n';
    }
    conns_[i].in.append(buf, static_cast<std::size_t>(got));
    for (;;) {
      // Looked up again each turn: on_line may send to (and so drop) connections.
      std::size_t j = 0;
      while (j < conns_.size() && conns_[j].id != id) ++j;
      if (j == conns_.size()) break;
      Conn& c = conns_[j];
      const std::size_t nl = c.in.find('\n');
      if (nl == std::string::npos) {
        if (c.in.size() > kMaxLine && !c.skipping) {
          c.skipping = true;
          c.in.clear();
          send(id, too_long());
        } else if (c.skipping) {
          c.in.clear();
        }
        break;
      }
      const std::string line = c.in.substr(0, nl);
      c.in.erase(0, nl + 1);
      if (c.skipping) {
        c.skipping = false;
        continue;
      }
      if (line.size() > kMaxLine) {
        send(id, too_long());
        continue;
      }
      on_line(id, line);
    }
    for (std::size_t j = 0; j < conns_.size(); ++j)
      if (conns_[j].id == id) {
        reap(j);
        break;
      }
  }
  if (p[0].revents & POLLIN) {
    for (;;) {
      const int c = accept4(fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (c < 0) break;
      if (conns_.size() >= kMaxClients) {
        static const char kFull[] = "error: too many control connections (at most 8)\n";
        static_assert(kMaxClients == 8, "the message names the limit");
        (void)!::send(c, kFull, sizeof kFull - 1, MSG_NOSIGNAL | MSG_DONTWAIT);
        ::close(c);
        continue;
      }
      conns_.push_back(Conn{c, next_++, {}, {}, false, false});
    }
  }
}

bool LineServer::reap(std::size_t i) {
  const Conn& c = conns_[i];
  const bool done = c.fd < 0 || (c.eof && c.out.empty() && !(busy && busy(c.id)));
  if (done) drop(i);
  return done;
}

void LineServer::send(Client id, const std::string& line) {
  for (std::size_t i = 0; i < conns_.size(); ++i) {
    if (conns_[i].id != id) continue;
    conns_[i].out += line;
    conns_[i].out += '\n';
    flush(conns_[i]);
    if (conns_[i].out.size() > kMaxPending) drop(i);
    else reap(i);
    return;
  }
}

void LineServer::flush(Conn& c) {
  while (!c.out.empty()) {
    const ssize_t w = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL);
    if (w < 0) {
      if (errno == EAGAIN || errno == EINTR) return;
      ::close(c.fd);  // the client went away: drop() removes it
      c.fd = -1;
      return;
    }
    c.out.erase(0, static_cast<std::size_t>(w));
  }
}

void LineServer::drop(std::size_t i) {
  const Client id = conns_[i].id;
  if (conns_[i].fd >= 0) ::close(conns_[i].fd);
  conns_.erase(conns_.begin() + static_cast<std::ptrdiff_t>(i));
  if (on_close) on_close(id);
}

}  // namespace ev3io
