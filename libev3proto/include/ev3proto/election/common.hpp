/// @file election/common.hpp
/// @brief What both sides of spec/tla/Election.tla share: its constants (kMaxMembership, the
///        score), the persistent variables (Durable), the sets a node keeps (IdSet, PeerTable),
///        the membership copy test, and Election's QuorumOf, the one quorum rule of the agent and
///        the master (election/agent.hpp, election/master.hpp). No heap, no exceptions, no I/O.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "../core.hpp"
#include "../decimal.hpp"
#include "../wire.hpp"

namespace ev3proto {

/// "Compute the score from the capabilities" (ElectionConfig::score).
inline constexpr std::uint32_t kAutoScore = ~std::uint32_t{0};

/// Most fleet members a membership holds (LEADER carries at most 30 besides epoch and leader).
inline constexpr std::size_t kMaxMembership = kMaxParams - 2;

/// LEADER @p m is a copy of a membership (leader 0: no master claimed) node @p me may learn: a
/// peer's or the PC's to it (ShareMembers), or the PC's broadcast as it stands (Election Teach:
/// one copy per agent in the spec). A master's LEADER names its sender as leader.
inline bool membership_copy(const Message& m, std::uint16_t me) noexcept {
  if (m.type != MsgType::LEADER || m.param_u16(1) != std::uint16_t{0}) return false;
  if (m.receiver == me) return is_assigned_id(m.sender) || m.sender == kMasterId;
  return m.receiver == kBroadcastId && m.sender == kMasterId;
}

/// What the firmware must keep on stable storage (Election's epoch and votedFor, and the
/// membership the agent knows: members, mepoch, floor): write it before sending the
/// datagrams polled after the call that changed it.
struct Durable {
  std::uint32_t epoch = 1;     ///< Highest epoch seen.
  std::uint16_t voted_for = 0; ///< Whom the agent voted for in that epoch (0 = nobody).
  std::uint32_t mepoch = 0;    ///< Epoch of the master that published the membership (0: none known).
  std::uint32_t floor = 0;     ///< No membership older than this epoch is current (Election floor).
  std::uint8_t member_count = 0;                  ///< Members in use.
  std::uint16_t members[kMaxMembership] = {};     ///< The membership quorums count against.
  /// Same epoch, vote and membership.
  friend constexpr bool operator==(const Durable& a, const Durable& b) noexcept {
    if (a.epoch != b.epoch || a.voted_for != b.voted_for || a.mepoch != b.mepoch || a.floor != b.floor ||
        a.member_count != b.member_count)
      return false;
    for (std::size_t i = 0; i < a.member_count; ++i)
      if (a.members[i] != b.members[i]) return false;
    return true;
  }
  /// Not the same.
  friend constexpr bool operator!=(const Durable& a, const Durable& b) noexcept { return !(a == b); }
};

/// Relay and election (spec/tla/Election.tla). Off by default: the agent is then exactly the
/// AgentLogic.tla agent (one master, epoch 1). `durable` holds Election's persistent variables
/// (epoch, votedFor, the membership): pass back what durable() said last (SD card) after a restart.
struct ElectionConfig {
  bool enabled = false;             ///< Relay and election on.
  Durable durable;                  ///< Restored from stable storage (a fresh agent: the defaults).
  std::uint32_t score = kAutoScore; ///< Election Score (lower = weaker, stands first, wins).
  /// Seed of the back-off's random part (Timer::backoff_jitter): the program draws it at start
  /// (msgids.hpp draw_start_ids' source). 0: no random part (deterministic: tests, replays).
  std::uint32_t seed = 0;
};

/// Which handler takes a datagram and what the Step prelude must do first, decided before any state
/// changes (Agent::Choose, AgentElection::Choose).
struct Verdict {
  Action action = Action::Ignore; ///< The handler (Ignore: none takes it; see why).
  Ignored why = Ignored::no;      ///< Why none takes it.
  Action inner = Action::Ignore;  ///< ApplyCommand: the AgentLogic handler of the inner datagram.
  std::uint32_t epoch = 0;        ///< The epoch the action moves the agent to (0: its own).
  bool stale = false;             ///< The sender is in an older epoch: answer EPOCH_STALE, nothing else.
};

/// A set of at most N agent ids in the order they were added (votes, pre-votes, the membership).
/// rev() changes whenever the set may have changed (trace records compare it).
template <std::size_t N>
class IdSet {
 public:
  /// Number of ids.
  std::size_t size() const noexcept { return n_; }
  /// The i-th id (0 when out of range).
  std::uint16_t operator[](std::size_t i) const noexcept { return i < n_ ? ids_[i] : 0; }
  /// True if @p id is in the set.
  bool contains(std::uint16_t id) const noexcept {
    for (std::size_t i = 0; i < n_; ++i)
      if (ids_[i] == id) return true;
    return false;
  }
  /// Adds @p id (nothing when full); the set counts as changed.
  void add(std::uint16_t id) noexcept {
    if (n_ < N) ids_[n_++] = id;
    ++rev_;
  }
  /// Empties the set (changed only if it was not empty).
  void clear() noexcept {
    if (n_ != 0) ++rev_;
    n_ = 0;
  }
  /// Empties the set; it counts as changed even if it was empty (a new count starts).
  void restart() noexcept {
    n_ = 0;
    ++rev_;
  }
  /// Changes whenever the set may have changed.
  std::uint32_t rev() const noexcept { return rev_; }
  /// The ids, in the order they were added.
  const std::uint16_t* begin() const noexcept { return ids_; }
  const std::uint16_t* end() const noexcept { return ids_ + n_; }

 private:
  std::uint16_t ids_[N] = {};
  std::size_t n_ = 0;
  std::uint32_t rev_ = 0;
};

/// Agents with the peer handle to reach them (relays, offered), at most N; adding to a full table
/// forgets the oldest entry.
template <std::size_t N>
class PeerTable {
 public:
  /// One agent and its peer handle.
  struct Entry {
    std::uint16_t id = 0; ///< Agent id.
    Peer peer = 0;        ///< Where it is.
  };
  /// Number of entries.
  std::size_t size() const noexcept { return n_; }
  /// True when no more entries fit.
  bool full() const noexcept { return n_ == N; }
  /// The i-th agent's id (0 when out of range).
  std::uint16_t id(std::size_t i) const noexcept { return i < n_ ? e_[i].id : 0; }
  /// The entry of @p id, or nullptr.
  const Entry* find(std::uint16_t id) const noexcept {
    for (std::size_t i = 0; i < n_; ++i)
      if (e_[i].id == id) return &e_[i];
    return nullptr;
  }
  /// Adds @p id at @p peer (an entry of @p id is updated); the table counts as changed.
  void add(std::uint16_t id, Peer peer) noexcept {
    ++rev_;
    for (std::size_t i = 0; i < n_; ++i)
      if (e_[i].id == id) {
        e_[i].peer = peer;
        return;
      }
    if (n_ == N) {
      for (std::size_t i = 1; i < n_; ++i) e_[i - 1] = e_[i];
      --n_;
    }
    e_[n_++] = Entry{id, peer};
  }
  /// Removes @p id (changed only if it was there).
  void remove(std::uint16_t id) noexcept {
    for (std::size_t i = 0; i < n_; ++i)
      if (e_[i].id == id) {
        for (std::size_t j = i + 1; j < n_; ++j) e_[j - 1] = e_[j];
        --n_;
        ++rev_;
        return;
      }
  }
  /// Empties the table (changed only if it was not empty).
  void clear() noexcept {
    if (n_ != 0) ++rev_;
    n_ = 0;
  }
  /// The i-th entry.
  const Entry& operator[](std::size_t i) const noexcept { return e_[i]; }
  /// Changes whenever the table may have changed.
  std::uint32_t rev() const noexcept { return rev_; }

 private:
  Entry e_[N] = {};
  std::size_t n_ = 0;
  std::uint32_t rev_ = 0;
};

/// What Election's guards need from the agent's lifecycle: its state (Election's life, with the
/// role), id, score, and whether it still hears the master it follows (Election HeartbeatOK, as far
/// as the agent can see it: heard within the loss timeout).
struct LifecycleView {
  State state = State::IDLE;     ///< The agent's state.
  std::uint16_t id = 0;          ///< Its id.
  std::uint32_t score = 0;       ///< Its score (lower = weaker).
  bool hears_master = false;     ///< Follows a master heard within the loss timeout.
  bool vouches = false;          ///< Follows a master directly, heard within the vouch time (Timer::vouch).
  Millis now = 0;                ///< Its time.
};

/// Whether @p id is in set @p s: an IdSet, or a sorted set of the master's (anything with count()).
template <std::size_t N>
bool Has(const IdSet<N>& s, std::uint16_t id) noexcept {
  return s.contains(id);
}
template <class Set>
bool Has(const Set& s, std::uint16_t id) noexcept {
  return s.count(id) != 0;
}

/// Election QuorumOf(S \cup {me}, L): the ids of @p s that are members of @p l, and @p me if it is
/// one (0: no own vote), are a strict majority of membership @p l; an empty membership has none.
/// The agent counts its pre-votes and votes with it, the master its votes (the one quorum rule).
template <class S, class L>
bool QuorumOf(const S& s, const L& l, std::uint16_t me) noexcept {
  std::size_t n = me != 0 && Has(l, me) ? 1u : 0u;
  for (const std::uint16_t id : s)
    if (id != me && Has(l, id)) ++n;
  return l.size() > 0 && 2 * n > l.size();
}

}  // namespace ev3proto
