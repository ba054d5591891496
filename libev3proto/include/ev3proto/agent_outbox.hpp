/// @file agent_outbox.hpp
/// @brief The agent core's datagrams waiting to be sent: each encoded once, stamped with the next
///        msgid, wrapped in RELAY when the agent is relayed, kept in a fixed queue that drops the
///        oldest when full. No heap.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "agent_types.hpp"
#include "core.hpp"
#include "messages.hpp"
#include "ring.hpp"
#include "wire.hpp"

namespace ev3proto {

/// The agent's output queue and its msgid counter (the spec's msgid: every datagram the agent
/// encodes takes the next one; a relay's forwarded datagram keeps its own).
/// @tparam Slots datagrams that can wait (the oldest is dropped when full).
/// @tparam Bytes the largest datagram.
template <std::size_t Slots, std::size_t Bytes>
class AgentOutbox {
 public:
  explicit AgentOutbox(std::uint32_t first_msgid) noexcept : msgid_(first_msgid) {}

  /// Encodes a datagram from @p from to @p to with the next msgid and queues it for @p dest
  /// (@p peer for Dest::peer). With @p via != 0 a datagram for the master travels inside
  /// RELAY(to, datagram) to relay @p via; the outer datagram carries the inner one's msgid. False,
  /// and nothing queued or counted, when it does not encode within Bytes.
  bool emit(std::uint16_t from, Dest dest, std::uint16_t to, MsgType type, const std::string_view* params,
            std::size_t count, Peer peer, std::uint16_t via) noexcept {
    // Encoded aside first: when the queue is full the slot written is the oldest datagram's, which
    // a refused encoding (the inner datagram or its RELAY envelope too long) must leave as it is.
    char buf[Bytes];
    EncodeResult r = encode_parts(from, to, msgid_, static_cast<std::uint8_t>(type), params, count, buf, Bytes);
    if (!r.ok()) return false;
    const char* bytes = buf;
    char outer[Bytes];
    if (dest == Dest::master && via != 0) {
      r = encode_envelope(from, via, msgid_, MsgType::RELAY, to, std::string_view(buf, r.size), outer, Bytes);
      if (!r.ok()) return false;
      bytes = outer;
    }
    ++msgid_;
    queue(dest, peer, std::string_view(bytes, r.size));
    return true;
  }
  /// Queues @p bytes unchanged (a relay forwarding an inner datagram): no msgid of ours. Longer
  /// than Bytes: dropped.
  void emit_raw(Dest dest, Peer peer, std::string_view bytes) noexcept {
    if (bytes.size() <= Bytes) queue(dest, peer, bytes);
  }
  /// Takes the oldest datagram; @p master_peer is where Dest::master goes. False when none.
  bool poll(Transmit& out, Peer master_peer) noexcept {
    if (tx_.empty()) return false;
    const Slot& s = tx_.front();
    out.dest = s.dest;
    out.peer = s.dest == Dest::master ? master_peer : s.dest == Dest::peer ? s.peer : 0;
    out.bytes = std::string_view(s.bytes, s.size);
    tx_.pop_front();  // the slot keeps its bytes until the next datagram is queued
    return true;
  }
  /// msgid the next datagram will carry.
  std::uint32_t next_msgid() const noexcept { return msgid_; }
  /// Datagrams dropped because the queue was full.
  std::uint32_t overflowed() const noexcept { return overflowed_; }

 private:
  struct Slot {
    Dest dest = Dest::broadcast;
    Peer peer = 0;
    std::size_t size = 0;
    char bytes[Bytes];
  };

  void queue(Dest dest, Peer peer, std::string_view bytes) noexcept {
    Slot& s = tx_.next();
    std::memcpy(s.bytes, bytes.data(), bytes.size());
    s.dest = dest;
    s.peer = peer;
    s.size = bytes.size();
    if (tx_.commit_over()) ++overflowed_;
  }

  Ring<Slot, Slots> tx_;
  std::uint32_t msgid_;
  std::uint32_t overflowed_ = 0;
};

}  // namespace ev3proto
