/// @file udp.hpp
/// @brief UDP transport of the programs: one non-blocking IPv4 socket with SO_BROADCAST; every
///        datagram goes out 3 times a few ms apart (copies share the msgid: they are the same
///        bytes), scheduled as deadlines of the event loop, never by sleeping. Optional seeded
///        fault injection (fault.hpp) applies to every copy. In signed mode each copy is signed as
///        it goes out (each its own counter: a receiver takes each copy once).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include <ev3proto/auth.hpp>
#include <ev3proto/core.hpp>

#include "ev3io/fault.hpp"

namespace ev3io {

/// An IPv4 address and port.
struct Endpoint {
  std::uint32_t addr = 0;  ///< Address in network byte order.
  std::uint16_t port = 0;  ///< Port in host byte order.
  /// "127.0.0.1:12345".
  std::string str() const;
  friend bool operator==(const Endpoint& a, const Endpoint& b) noexcept {
    return a.addr == b.addr && a.port == b.port;
  }
  friend bool operator<(const Endpoint& a, const Endpoint& b) noexcept {
    return a.addr != b.addr ? a.addr < b.addr : a.port < b.port;
  }
};

/// Parses a dotted IPv4 address or "localhost" into @p addr (network order).
bool parse_address(std::string_view s, std::uint32_t& addr) noexcept;
/// Parses "HOST:PORT" (PORT 1..65535).
bool parse_endpoint(std::string_view s, Endpoint& out) noexcept;

/// Counters of the transport.
struct UdpStats {
  std::uint64_t received = 0;    ///< Datagrams received.
  std::uint64_t sent = 0;        ///< Copies handed to the kernel.
  std::uint64_t send_errors = 0; ///< Copies the kernel refused.
  std::uint64_t too_big = 0;     ///< Datagrams over 4096 bytes refused by send().
};

/// The UDP socket, the copy schedule and the peer table (Peer handle <-> endpoint).
class UdpTransport {
 public:
  /// Copies of every datagram.
  static constexpr int kCopies = 3;
  /// Gap between two copies.
  static constexpr Millis kCopyGapMs = 3;

  explicit UdpTransport(const FaultConfig& faults = {}) : faults_(faults) {}
  ~UdpTransport();
  UdpTransport(const UdpTransport&) = delete;
  UdpTransport& operator=(const UdpTransport&) = delete;

  /// Binds @p addr:@p port (0 = any free port). False with a message in @p err.
  bool open(std::uint32_t addr, std::uint16_t port, std::string& err);
  /// The socket (for poll).
  int fd() const noexcept { return fd_; }
  /// The bound address.
  Endpoint local() const noexcept { return local_; }

  /// The peer handle of @p e (registered on first use; never 0).
  ev3proto::Peer peer_of(const Endpoint& e);
  /// The endpoint of handle @p p, or nullptr.
  const Endpoint* endpoint_of(ev3proto::Peer p) const noexcept;

  /// Schedules the 3 copies of @p bytes to @p to, the first at @p now. False when over 4096 bytes.
  bool send(const Endpoint& to, std::string_view bytes, Millis now);
  /// Sends every copy due at @p now.
  void flush(Millis now);
  /// Sends every copy still scheduled, now, ignoring their times (at exit).
  void flush_all();
  /// When the next copy is due (kNever when none).
  Millis next_send() const noexcept;
  /// Signed mode: every copy sent from now on is signed by @p s (its own counter each), kept by the
  /// caller; nullptr: unsigned.
  void sign_with(ev3proto::auth::Signer* s) noexcept { signer_ = s; }
  /// Takes one received datagram; false when none is waiting.
  bool receive(std::string& out, Endpoint& from);

  const UdpStats& stats() const noexcept { return stats_; }
  const FaultInjector& faults() const noexcept { return faults_; }

 private:
  struct Out {
    Endpoint to;
    std::string bytes;
  };
  void send_now(const Out& o);
  int fd_ = -1;
  Endpoint local_;
  FaultInjector faults_;
  std::multimap<Millis, Out> queue_;
  std::map<Endpoint, ev3proto::Peer> peers_;
  std::vector<Endpoint> by_handle_;
  std::vector<Millis> times_;
  std::vector<char> rxbuf_ = std::vector<char>(65536);
  ev3proto::auth::Signer* signer_ = nullptr;
  std::string sealed_;
  UdpStats stats_;
};

}  // namespace ev3io
