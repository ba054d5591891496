/// @file election.hpp
/// @brief One agent's part in relay and election (spec/tla/Election.tla): its Election variables and
///        the enabling condition of each Election rule, as Election.tla writes them per node.
///
/// Election.tla defines every action X of a node n by an enabling condition on the node's own
/// variables, XOk(n, s, m, ...), and the new local state XNext(s, m). AgentElection holds one
/// agent's variables (life is the agent core's State refined by a Role) and its XOk guards: `const`,
/// taking the datagram and what they need from the agent's lifecycle (Lifecycle) as parameters.
/// Which rule takes an election datagram is Choose(); the agent core (agent.hpp) runs the handler of
/// the same name, which composes the rule with the lifecycle and the network. No heap, no
/// exceptions, no I/O.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core.hpp"
#include "wire.hpp"

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
struct Lifecycle {
  State state = State::IDLE;     ///< The agent's state.
  std::uint16_t id = 0;          ///< Its id.
  std::uint32_t score = 0;       ///< Its score (lower = weaker).
  bool hears_master = false;     ///< Follows a master heard within the loss timeout.
};

/// One agent's Election.tla variables and the enabling conditions of Election's rules on them.
/// @tparam RelaySlots agents one relay serves at once (and pending offers).
/// @tparam MaxMembers fleet members kept (LEADER carries at most 30).
template <std::size_t RelaySlots, std::size_t MaxMembers>
class AgentElection {
 public:
  /// From the configuration (epoch 0 counts as 1): the restored epoch, vote and membership.
  explicit AgentElection(const ElectionConfig& c) noexcept
      : enabled(c.enabled), epoch(c.durable.epoch == 0 ? 1 : c.durable.epoch), voted_for(c.durable.voted_for),
        mepoch(c.durable.mepoch), floor(c.durable.floor) {
    for (std::size_t i = 0; i < c.durable.member_count && i < kMaxMembership; ++i)
      if (is_assigned_id(c.durable.members[i]) && !members.contains(c.durable.members[i]))
        members.add(c.durable.members[i]);
  }

  // ------------------------------------------------------------ Election's variables of the agent
  bool enabled;                    ///< Relay and election on.
  Role role = Role::none;          ///< life CANDIDATE / MASTER (the agent's state is then PANIC).
  std::uint32_t epoch;             ///< epoch
  std::uint16_t voted_for;         ///< votedFor (0 = NoNode)
  std::uint16_t leader = 0;        ///< leader (0 = NoNode)
  std::uint32_t following = 0;     ///< following
  std::uint16_t via = 0;           ///< via (0 = NoNode: direct)
  PeerTable<RelaySlots> relays;    ///< relays
  PeerTable<RelaySlots> offered;   ///< offered
  IdSet<MaxMembers> votes;         ///< votes (as a candidate)
  IdSet<MaxMembers> prevotes;      ///< prevotes (for standing in epoch + 1; always of this epoch)
  IdSet<MaxMembers> members;       ///< members: the membership last learned (LEADER or a peer's copy).
  std::uint32_t mepoch = 0;        ///< mepoch: the epoch of the master that published it (0: none).
  std::uint32_t floor = 0;         ///< floor: no membership older than this epoch is current.
  std::uint32_t master_epoch = 0;  ///< The epoch this agent last became master of (0 = never).

  /// Changes whenever relays, offered, votes or prevotes may have changed (trace records).
  std::uint32_t sets_rev() const noexcept {
    return relays.rev() + offered.rev() + votes.rev() + prevotes.rev();
  }
  /// The epoch, vote and membership to keep on stable storage.
  Durable durable() const noexcept {
    Durable d;
    d.epoch = epoch;
    d.voted_for = voted_for;
    d.mepoch = mepoch;
    d.floor = floor;
    for (std::size_t i = 0; i < members.size() && i < kMaxMembership; ++i) d.members[d.member_count++] = members[i];
    return d;
  }
  /// Election Learned(s, L, e): membership @p m (LEADER's params from the third on) is the one of
  /// epoch @p e; the floor rises to @p e (Raised). The list is rebuilt only when it is news
  /// (NewMembers): a master's every heartbeat repeats the list of its epoch.
  void Learned(const Message& m, std::uint32_t e) noexcept {
    if (NewMembers(m, e)) {
      members.clear();
      for (std::size_t i = 2; i < m.param_count() && members.size() < MaxMembers; ++i) {
        const auto id = m.param_u16(i);
        if (id && is_assigned_id(*id) && !members.contains(*id)) members.add(*id);
      }
    }
    mepoch = e;
    Raised(e);
  }
  /// Election NewMembers(s, m): LEADER @p m of epoch @p e lists another membership than the one we
  /// know (as a set: its agent ids), or is of another epoch.
  bool NewMembers(const Message& m, std::uint32_t e) const noexcept {
    if (e != mepoch) return true;
    auto listed = [&m](std::uint16_t id) {
      for (std::size_t i = 2; i < m.param_count(); ++i)
        if (m.param_u16(i) == id) return true;
      return false;
    };
    for (std::size_t i = 2; i < m.param_count(); ++i) {
      const auto id = m.param_u16(i);
      if (id && is_assigned_id(*id) && !members.contains(*id)) return true;
    }
    for (std::size_t i = 0; i < members.size(); ++i)
      if (!listed(members[i])) return true;
    return false;
  }
  /// Election Raised(s, e): the floor rises to @p e.
  void Raised(std::uint32_t e) noexcept {
    if (e > floor) floor = e;
  }

  // ------------------------------------------------------------ Election's predicates

  /// Follows a master (Election: life in Followers, leader set).
  bool Following(State s) const noexcept { return is_synced(s) && leader != 0; }
  /// Follows a master of its current epoch over a direct link (may offer and relay: one hop).
  bool DirectFollower(State s) const noexcept { return Following(s) && following == epoch && via == 0; }
  /// Election QuorumOf(S, members): the ids of @p s that are members, and @p me if it is one, are a
  /// strict majority of the membership (an empty one has none).
  template <std::size_t K>
  bool QuorumOf(const IdSet<K>& s, std::uint16_t me) const noexcept {
    std::size_t n = members.contains(me) ? 1u : 0u;
    for (std::size_t i = 0; i < s.size(); ++i)
      if (s[i] != me && members.contains(s[i])) ++n;
    return members.size() > 0 && 2 * n > members.size();
  }
  /// Election QuorumOf(prevotes \cup {me}, members).
  bool PreVoteQuorum(std::uint16_t me) const noexcept { return QuorumOf(prevotes, me); }
  /// Election Obeys: the command's sender is the master followed in epoch @p e, the highest seen.
  bool Obeys(std::uint16_t sender, std::uint32_t e) const noexcept {
    return leader == sender && following == e && e == epoch;
  }
  /// Election ElectGrant: not voted in the epoch yet (or for this candidate: its ELECT again,
  /// docs/core.md deviation 2), the candidate is not stronger than us, an agent candidate's
  /// membership (of epoch @p k, ELECT's members_epoch) is not older than our floor, and we know a
  /// membership at least as new as the one the PC counts against (Knows: our floor never rises
  /// above the list we know).
  bool ElectGrant(std::uint16_t candidate, std::uint32_t e, std::uint32_t its_score, std::uint32_t my_score,
                  std::uint32_t k) const noexcept {
    return (e > epoch || voted_for == 0 || voted_for == candidate) && its_score <= my_score &&
           (candidate == kMasterId ? Knows(k) : k >= floor);
  }
  /// Election Knows(s, k): we know a membership at least as new as epoch @p k.
  bool Knows(std::uint32_t k) const noexcept { return mepoch >= k; }

  // ------------------------------------------------------------ enabling conditions (XOk)

  /// Election RequestRelayOk (the retry timer is the agent's): PANIC or a candidate.
  bool RequestRelayOk(State s) const noexcept {
    return enabled && s == State::PANIC && role != Role::master;
  }
  /// Election OfferRelayOk: a direct follower of the current epoch offers to relay (one hop), not to
  /// an agent that has seen a newer epoch. An agent already in the table is offered to again.
  bool OfferRelayOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    return m.receiver == kBroadcastId && is_assigned_id(m.sender) && DirectFollower(me.state) && e &&
           *e <= epoch;
  }
  /// Election GrantPreVoteOk: no master here (PANIC or candidate), the asker's epoch not older than
  /// ours and its score (RELAY_REQ's second param) not higher than ours.
  bool GrantPreVoteOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto sc = m.param_u32(1);
    return m.receiver == kBroadcastId && is_assigned_id(m.sender) && is_assigned_id(me.id) &&
           me.state == State::PANIC && role != Role::master && e && sc && *e >= epoch &&
           *sc <= me.score;
  }
  /// Election HandlePreVoteOk: still without a master, for our current epoch, from a member not
  /// counted yet.
  bool HandlePreVoteOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    return ToMe(m, me) && me.state == State::PANIC && role != Role::master && e && *e == epoch &&
           !prevotes.contains(m.sender) && members.contains(m.sender);
  }
  /// Election AcceptRelayOk: PANIC (not standing), the offer's epoch not older.
  bool AcceptRelayOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto x = m.param_u16(1);
    return ToMe(m, me) && me.state == State::PANIC && role == Role::none && e && x && *x != 0 &&
           *x != me.id && *e >= epoch && is_assigned_id(m.sender);
  }
  /// Election HandleAcceptOk: answers an offer made since the master last changed, and the relay
  /// still follows that master in that epoch directly (and has room).
  bool HandleAcceptOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto x = m.param_u16(1);
    return ToMe(m, me) && Following(me.state) && via == 0 && e && x && *e == following &&
           *x == leader && offered.find(m.sender) != nullptr && !relays.full();
  }
  /// Election ForwardOk: a direct follower relaying for the target (master -> agent) or for the
  /// sender (agent -> master); @p inner, the datagram inside (nullptr: it does not decode), is not
  /// itself a RELAY.
  bool ForwardOk(const Message& m, const Message* inner, const Lifecycle& me) const noexcept {
    const auto target = m.param_u16(0);
    if (!ToMe(m, me) || !Following(me.state) || via != 0 || !target) return false;
    if (inner == nullptr || inner->type == MsgType::RELAY) return false;
    if (m.sender == leader) return relays.find(*target) != nullptr;
    return *target == leader && relays.find(m.sender) != nullptr && inner->sender == m.sender;
  }
  /// Election RelayDroppedOk: from our relay while following through it.
  bool RelayDroppedOk(const Message& m, const Lifecycle& me) const noexcept {
    return ToMe(m, me) && via != 0 && m.sender == via && is_synced(me.state);
  }
  /// Election StartElectionOk (the back-off timer is the agent's): PANIC or a candidate, an assigned
  /// id, a known membership not older than the floor, pre-votes of a majority of it (itself
  /// included), an epoch left.
  bool StartElectionOk(const Lifecycle& me) const noexcept {
    return enabled && me.state == State::PANIC && role != Role::master && is_assigned_id(me.id) &&
           epoch < 0xFFFFFFFFu && MembershipCurrent() && PreVoteQuorum(me.id);
  }
  /// Election's `mepoch >= floor`: the membership known is not older than one this agent voted to
  /// replace (it may stand and count against it).
  bool MembershipCurrent() const noexcept { return mepoch >= floor; }
  /// Election HandleElectOk (the CASE arms that change something): an older epoch (EPOCH_STALE);
  /// otherwise not a healthy follower (unless the PC stands), and a newer epoch or a vote to grant.
  bool HandleElectOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto sc = m.param_u32(1);
    if (m.receiver != kBroadcastId || !e || !sc || me.state == State::IDLE || !is_assigned_id(me.id))
      return false;
    if (*e < epoch) return true;                            // EPOCH_STALE
    if (me.hears_master && m.sender != kMasterId) return false;  // a healthy follower
    return *e > epoch || ElectGrant(m.sender, *e, *sc, me.score, m.param_u32(2).value_or(0));
  }
  /// Election HandleVoteOk: a candidate's vote of its epoch, from a member not counted yet.
  bool HandleVoteOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto c = m.param_u16(1);
    return ToMe(m, me) && role == Role::candidate && e && c && *e == epoch && *c == me.id &&
           !votes.contains(m.sender) && members.contains(m.sender);
  }
  /// Election BecomeMasterOk: a candidate of an epoch newer than its membership's (no membership
  /// of this epoch is published yet) with votes of a strict majority of the membership (QuorumOf:
  /// its own vote is among the votes when it is a member).
  bool BecomeMasterOk() const noexcept { return role == Role::candidate && epoch > mepoch && QuorumOf(votes, 0); }
  /// Election HandleHeartbeatOk: a master's LEADER (not an IDLE agent's business); an older one is
  /// answered EPOCH_STALE; a master takes only a newer one.
  bool HandleHeartbeatOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto s = m.param_u16(1);
    if (m.receiver != kBroadcastId || !e || !s || *s != m.sender || me.state == State::IDLE ||
        !is_assigned_id(me.id))
      return false;
    if (*e < epoch) return true;  // EPOCH_STALE
    return role != Role::master || *e > epoch;
  }
  /// Election ShareMembersOk: a peer's RELAY_REQ says it knows a membership older than ours (its
  /// members_epoch, 0 when absent), and we are not master: we send it a copy of our LEADER.
  bool ShareMembersOk(const Message& m, const Lifecycle& me) const noexcept {
    return enabled && m.type == MsgType::RELAY_REQ && m.receiver == kBroadcastId && is_assigned_id(m.sender) &&
           m.sender != me.id && is_assigned_id(me.id) && me.state != State::IDLE && role != Role::master &&
           mepoch > m.param_u32(2).value_or(0);
  }
  /// Election LearnMembersOk: a copy of a LEADER (leader 0: no master claimed) of a newer
  /// membership than ours: a peer's to us (ShareMembers), or the PC's broadcast as it stands (Teach:
  /// Election.tla sends one copy per agent).
  bool LearnMembersOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    return is_assigned_id(me.id) && membership_copy(m, me.id) && me.state != State::IDLE && e && *e > mepoch;
  }
  /// Election HandleStaleOk: a newer epoch than ours.
  bool HandleStaleOk(const Message& m, const Lifecycle& me) const noexcept {
    const auto e = m.param_u32(0);
    return ToMe(m, me) && e && *e > epoch;
  }

  /// Which Election rule takes relay / election datagram @p m (not EPOCH_CMD: the agent fences
  /// commands; @p inner: RELAY's inner datagram or nullptr), and what the prelude does first: an
  /// older epoch is answered EPOCH_STALE, a newer one is adopted.
  Verdict Choose(const Message& m, const Message* inner, const Lifecycle& me) const noexcept {
    const std::uint32_t e = m.param_u32(0).value_or(0);
    switch (m.type) {
      case MsgType::RELAY_REQ:  // ShareMembers may follow the first two (a record of its own)
        if (OfferRelayOk(m, me)) return Take(Action::OfferRelay);
        if (GrantPreVoteOk(m, me)) return Take(Action::GrantPreVote);
        if (ShareMembersOk(m, me)) return Take(Action::ShareMembers);
        break;
      case MsgType::PREVOTE_OK:
        if (HandlePreVoteOk(m, me)) return Take(Action::HandlePreVote);
        break;
      case MsgType::RELAY_OFFER:
        if (AcceptRelayOk(m, me)) return Take(Action::AcceptRelay, e);
        break;
      case MsgType::RELAY_ACCEPT:
        if (HandleAcceptOk(m, me)) return Take(Action::HandleAccept);
        break;
      case MsgType::RELAY:
        if (ForwardOk(m, inner, me)) return Take(Action::Forward);
        break;
      case MsgType::RELAY_DROP:
        if (RelayDroppedOk(m, me)) return Take(Action::RelayDropped);
        break;
      case MsgType::ELECT:
        if (HandleElectOk(m, me)) return Take(Action::HandleElect, e);
        break;
      case MsgType::VOTE:
        if (HandleVoteOk(m, me)) return Take(Action::HandleVote);
        break;
      case MsgType::LEADER:
        if (HandleHeartbeatOk(m, me)) return Take(Action::HandleHeartbeat, e);
        if (LearnMembersOk(m, me)) {  // never answered EPOCH_STALE: the copy's epoch may be older
          Verdict v = Take(Action::LearnMembers);
          if (e > epoch) v.epoch = e;
          return v;
        }
        break;
      case MsgType::EPOCH_STALE:
        if (HandleStaleOk(m, me)) return Take(Action::HandleStale, e);
        break;
      default: return Verdict{Action::Ignore, Ignored::not_for_agent};  // RELAY_ROUTE, HANDOVER
    }
    const bool mine = m.receiver == kBroadcastId || m.receiver == me.id;
    return Verdict{Action::Ignore, mine ? Ignored::ignored_in_state : Ignored::misaddressed};
  }

 private:
  static bool ToMe(const Message& m, const Lifecycle& me) noexcept {
    return m.receiver == me.id && is_assigned_id(me.id);
  }
  /// Rule @p a takes the datagram; it carries epoch @p e (older: stale; newer: adopted first).
  Verdict Take(Action a, std::uint32_t e = 0) const noexcept {
    Verdict v{a};
    if (e != 0 && e < epoch) v.stale = true;
    if (e > epoch) v.epoch = e;
    return v;
  }
};

}  // namespace ev3proto
