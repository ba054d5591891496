/// @file msgids.hpp
/// @brief The order of msgids and where a master's first msgid comes from (docs/protocol.md,
///        "Duplicates and stale copies").
///
/// An agent does not act on a command or MASTER below a msgid its dedupe window remembers from the
/// same sender (AgentLogic Stale): a copy that outlived its own window entry. That is sound only if
/// every master sends its msgids in increasing order and never reuses one, across its restarts too:
///  - ev3-master with --state-file continues above the block the file reserved (master/main.cpp);
///  - ev3-master without a state file starts at master_msgid_seed(wall clock): one msgid per
///    millisecond since 1970, so a restart starts above everything the previous run sent, if that run
///    sent fewer msgids than milliseconds passed since it started and the clock did not go back;
///  - the Master core an elected agent runs starts at elected_master_first_msgid(epoch): the epochs
///    it wins increase (they are durable), so its msgids do too.
/// "Below" is serial-number order (RFC 1982 style, msgid_newer): msgids wrap at 2^32.
#pragma once

#include <cstdint>

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

} // namespace ev3proto
