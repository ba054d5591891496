/// @file election/agent.hpp
/// @brief One agent's part in relay and election (spec/tla/Election.tla): its Election variables,
///        the enabling condition of each rule (XOk) and its transition (XNext), as Election.tla
///        writes them per node.
///
/// Election.tla defines every action X of a node n by an enabling condition on the node's own
/// variables, XOk(n, s, m, ...), and the new local state XNext(s, m). AgentElection holds one
/// agent's variables (life is the agent core's State refined by an ElectionRole), its XOk guards (`const`,
/// taking the datagram and what they need from the agent's lifecycle, LifecycleView, as parameters)
/// and its transitions, each named as the spec's action. A transition sends its datagrams through
/// the agent core and returns the lifecycle change it makes (LifecycleEffect), which the agent
/// applies through its own state table. Which rule takes an election datagram is Choose(); the
/// agent core's Step prelude (agent.hpp) runs it. No heap, no exceptions, no I/O.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "common.hpp"

namespace ev3proto {

/// What an election transition does to the agent's lifecycle, for the agent to apply through its
/// state table (by the action that took the step).
struct LifecycleEffect {
  bool pause = false;   ///< Election SteppedDown: a WORKING agent pauses (motors off, progress kept).
  bool follow = false;  ///< A master is followed at the datagram's peer: heard now; PANIC -> ACTIVE.
  bool panic = false;   ///< Lost: the lifecycle enters PANIC, then AgentElection::Panic.
};

/// One agent's Election.tla variables and the enabling conditions of Election's rules on them.
/// @tparam RelaySlots agents one relay serves at once (and pending offers).
/// @tparam MaxMembers fleet members kept (LEADER carries at most 30).
template <std::size_t RelaySlots, std::size_t MaxMembers>
class AgentElection {
 public:
  /// "No deadline".
  static constexpr Millis kNever = ~Millis{0};

  /// From the configuration (epoch 0 counts as 1): the restored epoch, vote and membership; the
  /// election's timers from @p t (relay_retry, backoff, backoff_step, backoff_jitter, candidate).
  AgentElection(const ElectionConfig& c, const Timers& t) noexcept
      : enabled(c.enabled), epoch(c.durable.epoch == 0 ? 1 : c.durable.epoch), voted_for(c.durable.voted_for),
        mepoch(c.durable.mepoch), floor(c.durable.floor), retry_(t[Timer::relay_retry]),
        backoff_(t[Timer::backoff]), backoff_step_(t[Timer::backoff_step]), candidate_(t[Timer::candidate]),
        jitter_(c.seed != 0 ? t[Timer::backoff_jitter] : 0), vouch_(t[Timer::vouch]), rng_(c.seed) {
    for (std::size_t i = 0; i < c.durable.member_count && i < kMaxMembership; ++i)
      if (is_assigned_id(c.durable.members[i]) && !members.contains(c.durable.members[i]))
        members.add(c.durable.members[i]);
  }

  // ------------------------------------------------------------ Election's variables of the agent
  bool enabled;                    ///< Relay and election on.
  ElectionRole role = ElectionRole::none;          ///< life CANDIDATE / MASTER (the agent's state is then PANIC).
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
  Millis relay_at = kNever;        ///< The next RELAY_REQ (RequestRelay), while masterless.
  Millis stand_at = kNever;        ///< The back-off's end (StartElection), while masterless.

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
  /// Election QuorumOf(prevotes \cup {me}, members).
  bool PreVoteQuorum(std::uint16_t me) const noexcept { return QuorumOf(prevotes, members, me); }
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
    return enabled && s == State::PANIC && role != ElectionRole::master;
  }
  /// Election OfferRelayOk: a direct follower of the current epoch offers to relay (one hop), not to
  /// an agent that has seen a newer epoch. An agent already in the table is offered to again. The
  /// timing the spec leaves out (Timer::vouch, 0: off): only for a master heard within the vouch
  /// time, so that a follower that has not yet noticed a dead master does not offer it.
  bool OfferRelayOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    return m.receiver == kBroadcastId && is_assigned_id(m.sender) && DirectFollower(me.state) && e &&
           *e <= epoch && me.vouches;
  }
  /// Election GrantPreVoteOk: no master here (PANIC or candidate), the asker's epoch not older than
  /// ours and its score (RELAY_REQ's second param) not higher than ours.
  bool GrantPreVoteOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto sc = m.param_u32(1);
    return m.receiver == kBroadcastId && is_assigned_id(m.sender) && is_assigned_id(me.id) &&
           me.state == State::PANIC && role != ElectionRole::master && e && sc && *e >= epoch &&
           *sc <= me.score;
  }
  /// Election HandlePreVoteOk: still without a master, for our current epoch, from a member not
  /// counted yet.
  bool HandlePreVoteOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    return ToMe(m, me) && me.state == State::PANIC && role != ElectionRole::master && e && *e == epoch &&
           !prevotes.contains(m.sender) && members.contains(m.sender);
  }
  /// Election AcceptRelayOk: PANIC (not standing), the offer's epoch not older. The timing the spec
  /// leaves out (Timer::vouch, 0: off): not, within the vouch time of declaring it lost, an offer of
  /// the master (and epoch) this agent has just lost (an offer late in the network).
  bool AcceptRelayOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto x = m.param_u16(1);
    return ToMe(m, me) && me.state == State::PANIC && role == ElectionRole::none && e && x && *x != 0 &&
           *x != me.id && *e >= epoch && is_assigned_id(m.sender) && !JustLost(*x, *e, me.now);
  }
  /// Master @p x of epoch @p e is the one this agent declared lost less than the vouch time ago.
  bool JustLost(std::uint16_t x, std::uint32_t e, Millis now) const noexcept {
    return vouch_ != 0 && x == lost_leader_ && e == lost_epoch_ && now < lost_at_ + vouch_;
  }
  /// Election HandleAcceptOk: answers an offer made since the master last changed, and the relay
  /// still follows that master in that epoch directly (and has room).
  bool HandleAcceptOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto x = m.param_u16(1);
    return ToMe(m, me) && Following(me.state) && via == 0 && e && x && *e == following &&
           *x == leader && offered.find(m.sender) != nullptr && !relays.full();
  }
  /// Election ForwardOk: a direct follower relaying for the target (master -> agent) or for the
  /// sender (agent -> master); @p inner, the datagram inside (nullptr: it does not decode), is not
  /// itself a RELAY.
  bool ForwardOk(const Message& m, const Message* inner, const LifecycleView& me) const noexcept {
    const auto target = m.param_u16(0);
    if (!ToMe(m, me) || !Following(me.state) || via != 0 || !target) return false;
    if (inner == nullptr || inner->type == MsgType::RELAY) return false;
    if (m.sender == leader) return relays.find(*target) != nullptr;
    return *target == leader && relays.find(m.sender) != nullptr && inner->sender == m.sender;
  }
  /// Election RelayDroppedOk: from our relay while following through it.
  bool RelayDroppedOk(const Message& m, const LifecycleView& me) const noexcept {
    return ToMe(m, me) && via != 0 && m.sender == via && is_synced(me.state);
  }
  /// Election StartElectionOk (the back-off timer is the agent's): PANIC or a candidate, an assigned
  /// id, a known membership not older than the floor, pre-votes of a majority of it (itself
  /// included), an epoch left.
  bool StartElectionOk(const LifecycleView& me) const noexcept {
    return enabled && me.state == State::PANIC && role != ElectionRole::master && is_assigned_id(me.id) &&
           EpochLeft() && MembershipCurrent() && PreVoteQuorum(me.id);
  }
  /// An epoch above this one exists to stand in (epochs are 32-bit on the wire; Election's MaxEpoch).
  bool EpochLeft() const noexcept { return epoch < 0xFFFFFFFFu; }
  /// Election's `mepoch >= floor`: the membership known is not older than one this agent voted to
  /// replace (it may stand and count against it).
  bool MembershipCurrent() const noexcept { return mepoch >= floor; }
  /// Election HandleElectOk (the CASE arms that change something): an older epoch (EPOCH_STALE);
  /// otherwise not a healthy follower (unless the PC stands), and a newer epoch or a vote to grant.
  bool HandleElectOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto sc = m.param_u32(1);
    if (m.receiver != kBroadcastId || !e || !sc || me.state == State::IDLE || !is_assigned_id(me.id))
      return false;
    if (*e < epoch) return true;                            // EPOCH_STALE
    if (me.hears_master && m.sender != kMasterId) return false;  // a healthy follower
    return *e > epoch || ElectGrant(m.sender, *e, *sc, me.score, m.param_u32(2).value_or(0));
  }
  /// Election HandleVoteOk: a candidate's vote of its epoch, from a member not counted yet.
  bool HandleVoteOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto c = m.param_u16(1);
    return ToMe(m, me) && role == ElectionRole::candidate && e && c && *e == epoch && *c == me.id &&
           !votes.contains(m.sender) && members.contains(m.sender);
  }
  /// Election BecomeMasterOk: a candidate of an epoch newer than its membership's (no membership
  /// of this epoch is published yet) with votes of a strict majority of the membership (QuorumOf:
  /// its own vote is among the votes when it is a member).
  bool BecomeMasterOk() const noexcept {
    return role == ElectionRole::candidate && epoch > mepoch && QuorumOf(votes, members, 0);
  }
  /// Election HandleHeartbeatOk: a master's LEADER (not an IDLE agent's business); an older one is
  /// answered EPOCH_STALE; a master takes only a newer one.
  bool HandleHeartbeatOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    const auto s = m.param_u16(1);
    if (m.receiver != kBroadcastId || !e || !s || *s != m.sender || me.state == State::IDLE ||
        !is_assigned_id(me.id))
      return false;
    if (*e < epoch) return true;  // EPOCH_STALE
    return role != ElectionRole::master || *e > epoch;
  }
  /// Election ShareMembersOk: a peer's RELAY_REQ says it knows a membership older than ours (its
  /// members_epoch, 0 when absent), and we are not master: we send it a copy of our LEADER.
  bool ShareMembersOk(const Message& m, const LifecycleView& me) const noexcept {
    return enabled && m.type == MsgType::RELAY_REQ && m.receiver == kBroadcastId && is_assigned_id(m.sender) &&
           m.sender != me.id && is_assigned_id(me.id) && me.state != State::IDLE && role != ElectionRole::master &&
           mepoch > m.param_u32(2).value_or(0);
  }
  /// Election LearnMembersOk: a copy of a LEADER (leader 0: no master claimed) of a newer
  /// membership than ours: a peer's to us (ShareMembers), or the PC's broadcast as it stands (Teach:
  /// Election.tla sends one copy per agent).
  bool LearnMembersOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    return is_assigned_id(me.id) && membership_copy(m, me.id) && me.state != State::IDLE && e && *e > mepoch;
  }
  /// Election HandleStaleOk: a newer epoch than ours.
  bool HandleStaleOk(const Message& m, const LifecycleView& me) const noexcept {
    const auto e = m.param_u32(0);
    return ToMe(m, me) && e && *e > epoch;
  }

  /// Which Election rule takes relay / election datagram @p m (not EPOCH_CMD: the agent fences
  /// commands; @p inner: RELAY's inner datagram or nullptr), and what the prelude does first: an
  /// older epoch is answered EPOCH_STALE, a newer one is adopted.
  Verdict Choose(const Message& m, const Message* inner, const LifecycleView& me) const noexcept {
    const std::uint32_t e = m.param_u32(0).value_or(0);
    // Every type here but RELAY carries an epoch first, and epochs start at 1 (the PC's before any
    // election): one of 0 is in no rule's guard (Election's epochs are 1..MaxEpoch), and a
    // handler that took it would follow, or learn the membership of, an epoch older than all.
    if (e == 0 && m.type != MsgType::RELAY && m.type != MsgType::RELAY_ROUTE && m.type != MsgType::HANDOVER)
      return Verdict{Action::Ignore, Ignored::ignored_in_state};  // (a master's own types: below)
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

  // ------------------------------------------------------------ the deadlines

  /// The back-off's end once it may be acted on: an epoch is left to stand in, the pre-votes make a
  /// quorum and the membership known is not older than the floor (without them the next event is a relay request's retry, a
  /// PREVOTE_OK arriving, or learning a newer membership, not the back-off's end).
  Millis StandDeadline(std::uint16_t me) const noexcept {
    return EpochLeft() && PreVoteQuorum(me) && MembershipCurrent() ? stand_at : kNever;
  }
  /// The earliest of the election's deadlines (relay request, standing) of agent @p me.
  Millis Deadline(std::uint16_t me) const noexcept {
    const Millis s = StandDeadline(me);
    return relay_at < s ? relay_at : s;
  }
  /// Back-off before standing: backoff + backoff_step for each weaker peer heard asking in this
  /// PANIC (its rank: the weakest stands first; GrantPreVote counts them and moves the standing on)
  /// and, with a seed, a random part in [0, backoff_jitter) drawn anew each time (raft's
  /// randomised election timeout: a split vote does not repeat). With the jitter below the step (the
  /// defaults: half of it), of two agents that entered PANIC together the weaker stands first.
  Millis Backoff(const LifecycleView&) noexcept { return backoff_ + weaker_.size() * backoff_step_ + Jitter(); }
  /// A draw in [0, backoff_jitter) (xorshift32 on the seed); 0 without a seed.
  Millis Jitter() noexcept {
    if (jitter_ == 0) return 0;
    rng_ ^= rng_ << 13;
    rng_ ^= rng_ >> 17;
    rng_ ^= rng_ << 5;
    return rng_ % jitter_;
  }

  // ------------------------------------------------------------ transitions (XNext)
  //
  // Each transition changes the election's variables and sends its datagrams through @p n (the
  // agent core: emit, emit_to, emit_raw); one that moves the agent's lifecycle returns it as a
  // LifecycleEffect, which the agent applies through its own state table.

  /// Spec RequestRelay: RELAY_REQ(epoch, score, mepoch) broadcast, again after relay_retry. It is
  /// also the pre-vote request (peers without a master answer PREVOTE_OK) and says which membership
  /// we know (a peer that knows a newer one sends us a copy: ShareMembers).
  template <class Net>
  void RequestRelay(const LifecycleView& me, Net& n) noexcept {
    relay_at = me.now + retry_;
    char num[10], sc[10], mk[10];
    const std::string_view p[3] = {decimal(epoch, num), decimal(me.score, sc), decimal(mepoch, mk)};
    n.emit(Dest::broadcast, kBroadcastId, MsgType::RELAY_REQ, p, 3);
  }

  /// Spec ShareMembers: a copy of the LEADER that published our membership, LEADER(mepoch, 0,
  /// members...) to the asker (leader 0: no master is claimed); nothing else changes.
  template <class Net>
  void ShareMembers(const Message& m, Peer from, Net& n) noexcept {
    emit_leader(mepoch, 0, m.sender, from, n);
  }

  /// Spec LearnMembers (a newer epoch was adopted by the prelude, as from EPOCH_STALE): the copy's
  /// membership is the one of its epoch; without a master we may now stand with it.
  void LearnMembers(const Message& m, const LifecycleView& me) noexcept {
    Learned(m, *m.param_u32(0));
    if (me.state == State::PANIC && role == ElectionRole::none && stand_at == kNever && members.size() > 0)
      stand_at = me.now + Backoff(me);
  }

  /// Spec GrantPreVote: PREVOTE_OK(epoch of the request) to the asker; nothing else of the spec's
  /// changes. The timing the spec leaves out: an asker weaker than us (a lower score, or an equal
  /// one and a lower id), counted once per PANIC, puts our standing one backoff_step later.
  template <class Net>
  void GrantPreVote(const Message& m, Peer from, const LifecycleView& me, Net& n) noexcept {
    const std::string_view p[1] = {m.param(0)};
    n.emit_to(from, m.sender, MsgType::PREVOTE_OK, p, 1);
    const std::uint32_t sc = *m.param_u32(1);  // GrantPreVoteOk: present, not above ours
    if ((sc < me.score || m.sender < me.id) && !weaker_.contains(m.sender) && weaker_.size() < kMaxMembership) {
      weaker_.add(m.sender);
      if (stand_at != kNever) stand_at += backoff_step_;
    }
  }

  /// Spec HandlePreVote: one more pre-vote for standing in the next epoch.
  void HandlePreVote(const Message& m) noexcept { prevotes.add(m.sender); }

  /// Spec OfferRelay: RELAY_OFFER(epoch, master) to the requester, remembered in offered.
  template <class Net>
  void OfferRelay(const Message& m, Peer from, Net& n) noexcept {
    offered.add(m.sender, from);
    char num[10], who[10];
    const std::string_view p[2] = {decimal(epoch, num), decimal(leader, who)};
    n.emit_to(from, m.sender, MsgType::RELAY_OFFER, p, 2);
  }

  /// Spec AcceptRelay: follow the relay's master in its epoch through it, RELAY_ACCEPT; the agent
  /// follows (PANIC -> ACTIVE).
  template <class Net>
  LifecycleEffect AcceptRelay(const Message& m, Peer from, Net& n) noexcept {
    become_follower(*m.param_u16(1), *m.param_u32(0), m.sender);
    const std::string_view p[2] = {m.param(0), m.param(1)};
    n.emit_to(from, m.sender, MsgType::RELAY_ACCEPT, p, 2);
    return LifecycleEffect{false, true, false};
  }

  /// Spec HandleAccept: the agent enters the relay table; RELAY_ROUTE(epoch, agent) to the master.
  template <class Net>
  void HandleAccept(const Message& m, Peer from, Net& n) noexcept {
    offered.remove(m.sender);
    relays.add(m.sender, from);
    char num[10], who[10];
    const std::string_view p[2] = {decimal(epoch, num), decimal(m.sender, who)};
    n.emit(Dest::master, leader, MsgType::RELAY_ROUTE, p, 2);
  }

  /// Spec Forward: the inner datagram goes on unchanged (sender, msgid: dedupe end to end). To the
  /// relayed agent it goes bare; to the master inside RELAY(master, datagram) from the relay, with
  /// the inner msgid (as the master wraps its own to a relayed agent), so that what the relay sends
  /// under its id is its own datagram: in signed mode the relay signs it, and the relayed agent's
  /// counter at the master stays the agent's own. An envelope over the datagram limit: dropped.
  template <class Net>
  void Forward(const Message& m, Net& n) noexcept {
    if (m.sender == leader) {
      n.emit_raw(Dest::peer, relays.find(*m.param_u16(0))->peer, m.param(1));
    } else {
      char out[kMaxDatagram];
      const EncodeResult r = encode_envelope(m.receiver, leader, m.msgid, MsgType::RELAY, leader, m.param(1), out,
                                             sizeof out);
      if (r.ok()) n.emit_raw(Dest::master, 0, std::string_view(out, r.size));
    }
  }

  /// Spec RelayDropped: back to PANIC (the agent's lifecycle first, then Panic()).
  LifecycleEffect RelayDropped(const Message&) noexcept { return LifecycleEffect{false, false, true}; }

  /// Spec TimeoutNext's and RelayDroppedNext's PANIC, the election's part (after the agent's
  /// lifecycle entered PANIC): nobody followed (the relay table dropped with RELAY_DROP), then
  /// masterless (relay requests at once, standing after the back-off).
  template <class Net>
  void Panic(const LifecycleView& me, Net& n) noexcept {
    if (leader != 0) {  // the master declared lost (JustLost)
      lost_leader_ = leader;
      lost_epoch_ = following;
      lost_at_ = me.now;
    }
    unfollow(n);
    become_masterless(me);
  }

  /// Spec StartElection: epoch + 1, vote for itself, ELECT(epoch, score, mepoch) broadcast.
  template <class Net>
  void StartElection(const LifecycleView& me, Net& n) noexcept {
    become_candidate(me);
    emit_elect(me, n);
  }
  /// A candidate's ELECT once more, each heartbeat of its candidacy (the spec's network duplicates
  /// it; docs/core.md, election deviation 9): a voter that missed it votes, one that voted votes
  /// again (deviation 2), so a lost ELECT or VOTE costs a heartbeat, not a new epoch after the
  /// candidate period and a back-off.
  template <class Net>
  void RepeatElect(const LifecycleView& me, Net& n) noexcept {
    if (role == ElectionRole::candidate) emit_elect(me, n);
  }

  /// Spec HandleElect (a newer epoch was adopted by the prelude): grant the one vote of the epoch
  /// to a candidate not stronger than us whose membership is not older than our floor (VOTE), and
  /// give it time to win before standing ourselves. A vote for the PC raises the floor to the epoch
  /// of its membership (Election Voted): it may be replacing it.
  template <class Net>
  void HandleElect(const Message& m, Peer from, const LifecycleView& me, Net& n) noexcept {
    const std::uint32_t e = *m.param_u32(0);
    const std::uint32_t k = m.param_u32(2).value_or(0);
    if (!ElectGrant(m.sender, e, *m.param_u32(1), me.score, k)) return;
    voted_for = m.sender;
    if (m.sender == kMasterId) Raised(k);
    if (me.state == State::PANIC && role == ElectionRole::none) stand_at = me.now + candidate_ + Backoff(me);
    char num[10], who[10];
    const std::string_view p[2] = {decimal(e, num), decimal(m.sender, who)};
    n.emit_to(from, m.sender, MsgType::VOTE, p, 2);
  }

  /// Spec HandleVote: one more vote.
  void HandleVote(const Message& m) noexcept { votes.add(m.sender); }

  /// Spec BecomeMaster: master of its epoch with the membership it counted against (now of this
  /// epoch: mepoch, floor); first LEADER(epoch, id, members) broadcast; a Master core runs for it
  /// from now on (node.hpp).
  template <class Net>
  void BecomeMaster(const LifecycleView& me, Net& n) noexcept {
    become_master();
    mepoch = epoch;
    Raised(epoch);
    emit_leader(epoch, me.id, kBroadcastId, 0, n);
  }

  /// Spec HandleHeartbeat (a newer epoch was adopted by the prelude): follow this master directly
  /// (PANIC / candidate / master -> ACTIVE; WORKING whose master changed -> PAUSED), learn the
  /// membership, and drop the relay table when the master changed.
  template <class Net>
  LifecycleEffect HandleHeartbeat(const Message& m, Net& n) noexcept {
    const std::uint32_t e = *m.param_u32(0);
    const bool changed = leader != m.sender || following != e;
    if (changed) drop_relays(n);
    become_follower(m.sender, e, 0);
    Learned(m, e);
    return LifecycleEffect{changed, true, false};
  }

  /// Spec HandleStale: the newer epoch is all it brings; the prelude adopted it (stepping down).
  void HandleStale(const Message&) noexcept {}

  /// A newer epoch @p e than ours, seen in a datagram a handler takes: SteppedDown, then the epoch
  /// is adopted with no vote and no pre-votes in it.
  template <class Net>
  void NewerEpoch(std::uint32_t e, const LifecycleView& me, Net& n) noexcept {
    SteppedDown(me, n);
    epoch = e;
    voted_for = 0;
    prevotes.clear();
  }
  /// Election SteppedDown(n, s), the election's part (the agent pauses a WORKING behaviour): a
  /// candidate or master is masterless again, the old master is not followed.
  template <class Net>
  void SteppedDown(const LifecycleView& me, Net& n) noexcept {
    if (role != ElectionRole::none) become_masterless(me);
    unfollow(n);
  }

  /// EPOCH_STALE(epoch) to @p to at @p peer: the sender is behind.
  template <class Net>
  void AnswerStale(std::uint16_t to, Peer peer, Net& n) noexcept {
    char num[10];
    const std::string_view p[1] = {decimal(epoch, num)};
    n.emit_to(peer, to, MsgType::EPOCH_STALE, p, 1);
  }

  // ------------------------------------------------------------ role changes (raft's become*)

  /// Follow master @p l of epoch @p e, through relay @p v (0: directly): no role, no relay
  /// requests, no standing, no pre-votes.
  void become_follower(std::uint16_t l, std::uint32_t e, std::uint16_t v) noexcept {
    set_role(ElectionRole::none);
    leader = l;
    following = e;
    via = v;
    relay_at = stand_at = kNever;
    prevotes.clear();
  }

 private:
  /// Without a master (PANIC, or a candidate / master stepping down): no role; with the election on
  /// and an assigned id, relay requests at once and standing after the back-off.
  void become_masterless(const LifecycleView& me) noexcept {
    set_role(ElectionRole::none);
    prevotes.clear();
    weaker_.clear();
    if (!enabled) return;
    const bool can = is_assigned_id(me.id);
    relay_at = can ? me.now : kNever;
    stand_at = can && members.size() > 0 ? me.now + Backoff(me) : kNever;
  }
  /// ELECT(epoch, score, mepoch) broadcast: the candidacy of the current epoch.
  template <class Net>
  void emit_elect(const LifecycleView& me, Net& n) noexcept {
    char e[10], sc[10], mk[10];
    const std::string_view p[3] = {decimal(epoch, e), decimal(me.score, sc), decimal(mepoch, mk)};
    n.emit(Dest::broadcast, kBroadcastId, MsgType::ELECT, p, 3);
  }
  /// Stand in the next epoch: vote for itself, count its own vote, ask again (pre-votes for the
  /// epoch after) if this candidacy stalls, then stand again after the back-off.
  void become_candidate(const LifecycleView& me) noexcept {
    ++epoch;
    voted_for = me.id;
    votes.restart();
    if (members.contains(me.id)) votes.add(me.id);
    set_role(ElectionRole::candidate);
    prevotes.clear();
    relay_at = me.now + candidate_;
    stand_at = me.now + candidate_ + Backoff(me);
  }
  /// Master of its epoch: a Master core runs for it (node.hpp); no relay requests, no standing.
  void become_master() noexcept {
    set_role(ElectionRole::master);
    relay_at = stand_at = kNever;
  }
  /// The role changes (only through the become_* functions): a candidate's votes are forgotten when
  /// it is one no more; becoming master records the epoch won.
  void set_role(ElectionRole r) noexcept {
    if (r == role) return;
    if (r == ElectionRole::master) master_epoch = epoch;
    role = r;
    if (r != ElectionRole::candidate) votes.clear();
  }
  /// leader, following, via cleared; relays dropped (RELAY_DROP), offers forgotten.
  template <class Net>
  void unfollow(Net& n) noexcept {
    leader = 0;
    following = 0;
    via = 0;
    drop_relays(n);
  }
  /// Every relayed agent gets RELAY_DROP(epoch); the relay table and the offers are forgotten.
  template <class Net>
  void drop_relays(Net& n) noexcept {
    for (std::size_t i = 0; i < relays.size(); ++i) {
      char num[10];
      const std::string_view p[1] = {decimal(epoch, num)};
      n.emit_to(relays[i].peer, relays[i].id, MsgType::RELAY_DROP, p, 1);
    }
    relays.clear();
    offered.clear();
  }
  /// LEADER(@p e, @p l, members...): our membership, the one of epoch @p e; broadcast by a new
  /// master (BecomeMaster), or a copy to peer @p to at @p peer (ShareMembers: leader 0).
  template <class Net>
  void emit_leader(std::uint32_t e, std::uint16_t l, std::uint16_t to, Peer peer, Net& n) noexcept {
    char ep[10], who[10], ids[kMaxMembership][10];
    std::string_view p[kMaxParams];
    p[0] = decimal(e, ep);
    p[1] = decimal(l, who);
    for (std::size_t i = 0; i < members.size(); ++i) p[2 + i] = decimal(members[i], ids[i]);
    if (to == kBroadcastId)
      n.emit(Dest::broadcast, kBroadcastId, MsgType::LEADER, p, 2 + members.size());
    else
      n.emit_to(peer, to, MsgType::LEADER, p, 2 + members.size());
  }

 private:
  static bool ToMe(const Message& m, const LifecycleView& me) noexcept {
    return m.receiver == me.id && is_assigned_id(me.id);
  }
  /// Rule @p a takes the datagram; it carries epoch @p e (older: stale; newer: adopted first).
  Verdict Take(Action a, std::uint32_t e = 0) const noexcept {
    Verdict v{a};
    if (e != 0 && e < epoch) v.stale = true;
    if (e > epoch) v.epoch = e;
    return v;
  }

  Millis retry_, backoff_, backoff_step_, candidate_, jitter_, vouch_;  // the election's timers (Timers)
  std::uint32_t rng_;  // the back-off's random state (ElectionConfig::seed)
  IdSet<kMaxMembership> weaker_;  // weaker peers heard asking in this PANIC (Backoff's rank)
  std::uint16_t lost_leader_ = 0;  // the master last declared lost (Panic), in epoch lost_epoch_, at lost_at_
  std::uint32_t lost_epoch_ = 0;
  Millis lost_at_ = 0;
};

}  // namespace ev3proto
