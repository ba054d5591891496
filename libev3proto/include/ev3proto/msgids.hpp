/// @file msgids.hpp
/// @brief The order of msgids and where a master's first msgid comes from (docs/protocol.md,
///        "Duplicates and stale copies").
///
/// An agent does not act on a command or MASTER below a msgid its dedupe window remembers from the
/// same sender (AgentLogic Stale): a copy that outlived its own window entry. That is sound only if
/// every master sends its msgids in increasing order and never reuses one, across its restarts too:
///  - ev3-master with --state-file continues above the block its state file reserved
///    (MsgidReservation: the file holds the end of a block of kMsgidBlock msgids);
///  - ev3-master without a state file starts at master_msgid_seed(wall clock): one msgid per
///    millisecond since 1970, so a restart starts above everything the previous run sent, if that run
///    sent fewer msgids than milliseconds passed since it started and the clock did not go back;
///  - the Master core an elected agent runs starts at elected_master_first_msgid(epoch): the epochs
///    it wins increase (they are durable), so its msgids do too;
///  - an agent core starts at a random msgid in 1..10^9 (draw_start_ids), below the elected Master
///    core's.
/// "Below" is serial-number order (RFC 1982 style, msgid_newer): msgids wrap at 2^32.
#pragma once

#include <cstdint>

#include "core.hpp"

namespace ev3proto {

/// True when msgid @p a comes after @p b in serial-number order: 1 <= (a - b) mod 2^32 < 2^31.
/// Two msgids 2^31 or more apart compare "not newer" both ways: the windows compare recent ones.
constexpr bool msgid_newer(std::uint32_t a, std::uint32_t b) noexcept {
  return static_cast<std::uint32_t>(a - b - 1u) < 0x7FFFFFFFu;
}

/// The first msgid of an ev3-master without a state file, from the wall clock (ms since 1970,
/// taken modulo 2^32; 0 becomes 1). Serial order makes the wrap (every 49.7 days) harmless as long
/// as an agent's window holds no msgid of this master older than 24.8 days.
constexpr std::uint32_t master_msgid_seed(std::uint64_t unix_ms) noexcept {
  const auto s = static_cast<std::uint32_t>(unix_ms);
  return s == 0 ? 1u : s;
}

/// The elected Master core's msgids live in [2^30, 2^31): the agent core's (same sender id) start
/// below 10^9 (ev3-agent draws them in 1..10^9), so the two never meet unless the agent core sends
/// more than 2^30 - 10^9 (73 million) datagrams in one life; below 2^31, TLC's integers, so real
/// runs can be checked against the spec (docs/spec.md "Implementation -> spec").
inline constexpr std::uint32_t kElectedMsgidBase = 1u << 30;
/// Msgids an elected Master core may send in one epoch before it would reach the next epoch's
/// (2^22: 11 hours at 100 datagrams a second).
inline constexpr std::uint32_t kElectedMsgidsPerEpoch = 1u << 22;
/// Epochs after which the elected Master core's first msgid comes round again.
inline constexpr std::uint32_t kElectedMsgidEpochs = (1u << 30) / kElectedMsgidsPerEpoch;

/// The first msgid of the Master core an agent runs as master of @p epoch: a block of
/// kElectedMsgidsPerEpoch per epoch above kElectedMsgidBase. A node wins each epoch at most once
/// and the epochs it wins increase (Election.tla, durable in ev3-agent.state), so a restarted
/// node, elected again, starts above every msgid it sent as master before -- within
/// kElectedMsgidEpochs (256) epochs, beyond which the blocks come round again.
constexpr std::uint32_t elected_master_first_msgid(std::uint32_t epoch) noexcept {
  return kElectedMsgidBase + (epoch % kElectedMsgidEpochs) * kElectedMsgidsPerEpoch;
}

/// Msgids a master with a state file reserves per write: the file holds the end of the block in
/// use, so a restarted master continues above every msgid it may have sent, without a write per
/// datagram.
inline constexpr std::uint32_t kMsgidBlock = 4096;

/// The end of the msgid block a master with a state file has reserved (Master::ready() keeps one).
class MsgidReservation {
 public:
  /// True when a master whose next msgid is @p next must reserve again before sending: nothing is
  /// reserved yet, or less than half a block is left.
  constexpr bool low(std::uint32_t next) const noexcept {
    return !reserved_ || !msgid_newer(end_, next + kMsgidBlock / 2);
  }
  /// Reserves the block from @p next on; returns its end, the next_msgid to write to stable storage.
  constexpr std::uint32_t reserve(std::uint32_t next) noexcept {
    end_ = next + kMsgidBlock;
    reserved_ = true;
    return end_;
  }
  /// The end of the block reserved last (0 before the first).
  constexpr std::uint32_t end() const noexcept { return end_; }

 private:
  std::uint32_t end_ = 0;
  bool reserved_ = false;
};

/// An agent core's temporary id and first msgid (AgentConfig::temp_id, first_msgid).
struct StartIds {
  std::uint16_t temp_id = 0;     ///< kFirstTempId..65535.
  std::uint32_t first_msgid = 1; ///< 1..10^9: below the elected Master core's (kElectedMsgidBase).
};

/// Draws the temporary id and the first msgid from @p random (64 random bits the program supplies:
/// the library does no I/O): the id from the low bits, the msgid from bits 20 on. Two agents
/// starting together announce distinct temporary ids unless their draws meet (1 in 15536), and a
/// restarted agent's first msgids are unlikely to meet what a master remembers of its last run.
constexpr StartIds draw_start_ids(std::uint64_t random) noexcept {
  StartIds s;
  s.temp_id = static_cast<std::uint16_t>(kFirstTempId + random % (0x10000u - kFirstTempId));
  s.first_msgid = static_cast<std::uint32_t>(1u + (random >> 20) % 1000000000u);
  return s;
}
static_assert(1000000000u < kElectedMsgidBase, "an agent core's first msgid lies below the elected Master core's");

} // namespace ev3proto
