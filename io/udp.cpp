#include "ev3io/udp.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <ev3proto/wire.hpp>

#include "ev3io/loop.hpp"

namespace ev3io {

std::string Endpoint::str() const {
  char a[INET_ADDRSTRLEN] = "?";
  in_addr ia{};
  ia.s_addr = addr;
  inet_ntop(AF_INET, &ia, a, sizeof a);
  return std::string(a) + ":" + std::to_string(port);
}

bool parse_address(std::string_view s, std::uint32_t& addr) noexcept {
  if (s == "localhost") s = "127.0.0.1";
  if (s.empty() || s.size() > 15) return false;
  char buf[16];
  std::memcpy(buf, s.data(), s.size());
  buf[s.size()] = '\0';
  in_addr ia{};
  if (inet_pton(AF_INET, buf, &ia) != 1) return false;
  addr = ia.s_addr;
  return true;
}

bool parse_endpoint(std::string_view s, Endpoint& out) noexcept {
  const std::size_t colon = s.rfind(':');
  if (colon == std::string_view::npos) return false;
  std::uint32_t a = 0;
  if (!parse_address(s.substr(0, colon), a)) return false;
  const std::string_view p = s.substr(colon + 1);
  if (p.empty() || p.size() > 5 || p[0] == '0') return false;
  unsigned long v = 0;
  for (char c : p) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<unsigned long>(c - '0');
  }
  if (v == 0 || v > 65535) return false;
  out.addr = a;
  out.port = static_cast<std::uint16_t>(v);
  return true;
}

UdpTransport::~UdpTransport() {
  if (fd_ >= 0) close(fd_);
}

bool UdpTransport::open(std::uint32_t addr, std::uint16_t port, std::string& err) {
  fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) {
    err = std::string("socket: ") + std::strerror(errno);
    return false;
  }
  const int one = 1;
  setsockopt(fd_, SOL_SOCKET, SO_BROADCAST, &one, sizeof one);
  const int rcvbuf = 1 << 20;
  setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_addr.s_addr = addr;
  sa.sin_port = htons(port);
  if (bind(fd_, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
    err = "bind " + Endpoint{addr, port}.str() + ": " + std::strerror(errno);
    return false;
  }
  socklen_t len = sizeof sa;
  getsockname(fd_, reinterpret_cast<sockaddr*>(&sa), &len);
  local_.addr = sa.sin_addr.s_addr;
  local_.port = ntohs(sa.sin_port);
  return true;
}

ev3proto::Peer UdpTransport::peer_of(const Endpoint& e) {
  auto it = peers_.find(e);
  if (it != peers_.end()) return it->second;
  by_handle_.push_back(e);
  const auto h = static_cast<ev3proto::Peer>(by_handle_.size());
  peers_.emplace(e, h);
  return h;
}

const Endpoint* UdpTransport::endpoint_of(ev3proto::Peer p) const noexcept {
  if (p == 0 || p > by_handle_.size()) return nullptr;
  return &by_handle_[p - 1];
}

bool UdpTransport::send(const Endpoint& to, std::string_view bytes, Millis now) {
  if (bytes.size() > ev3proto::kMaxDatagram) {
    ++stats_.too_big;
    return false;
  }
  for (int i = 0; i < kCopies; ++i) {
    times_.clear();
    faults_.schedule(now + static_cast<Millis>(i) * kCopyGapMs, times_);
    for (Millis t : times_) queue_.emplace(t, Out{to, std::string(bytes)});
  }
  return true;
}

void UdpTransport::send_now(const Out& o) {
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_addr.s_addr = o.to.addr;
  sa.sin_port = htons(o.to.port);
  std::string_view out = o.bytes;
  if (signer_ != nullptr) {
    sealed_.assign(o.bytes);
    sealed_.resize(o.bytes.size() + ev3proto::auth::kTrailer);
    signer_->seal(o.bytes, sealed_.data() + o.bytes.size());
    out = sealed_;
  }
  const ssize_t n = sendto(fd_, out.data(), out.size(), 0, reinterpret_cast<const sockaddr*>(&sa), sizeof sa);
  if (n < 0)
    ++stats_.send_errors;
  else
    ++stats_.sent;
}

void UdpTransport::flush(Millis now) {
  while (!queue_.empty() && queue_.begin()->first <= now) {
    send_now(queue_.begin()->second);
    queue_.erase(queue_.begin());
  }
}

void UdpTransport::flush_all() {
  for (const auto& kv : queue_) send_now(kv.second);
  queue_.clear();
}

Millis UdpTransport::next_send() const noexcept {
  return queue_.empty() ? kNever : queue_.begin()->first;
}

bool UdpTransport::receive(std::string& out, Endpoint& from) {
  sockaddr_in sa{};
  socklen_t len = sizeof sa;
  const ssize_t n = recvfrom(fd_, rxbuf_.data(), rxbuf_.size(), MSG_TRUNC,
                             reinterpret_cast<sockaddr*>(&sa), &len);
  if (n < 0) return false;
  ++stats_.received;
  // MSG_TRUNC gives the real length: a datagram over the buffer is still seen as "too long".
  const std::size_t got = static_cast<std::size_t>(n) < rxbuf_.size() ? static_cast<std::size_t>(n) : rxbuf_.size();
  out.assign(rxbuf_.data(), got);
  if (static_cast<std::size_t>(n) > got) out.append(1, '\0');
  from.addr = sa.sin_addr.s_addr;
  from.port = ntohs(sa.sin_port);
  return true;
}

}  // namespace ev3io
