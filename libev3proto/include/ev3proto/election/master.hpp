/// @file election/master.hpp
/// @brief The master node's part in relay and election (spec/tla/Election.tla): its Election
///        variables, the enabling condition of each rule (XOk) and its transition, as Election.tla
///        writes them for the PC and for an agent that won an epoch (which runs a Master core).
///
/// The two masters differ in a few rules only; MasterPolicy names each difference, and the Master
/// core picks one of the two policies (kPcPolicy, kElectedAgentPolicy) once, at construction, by
/// its id. A transition sends its datagrams through the Master core (broadcast, send) and reads
/// its registry (the agents registered and synced are wanted in the membership: Want). The PC may
/// allocate: the sets are std::set.
#pragma once

#include <cstddef>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "common.hpp"

namespace ev3proto {

/// The master's part in the election (Election.tla life of the master node).
enum class MasterRole : std::uint8_t {
  master,       ///< MASTER: commands, LEADER heartbeats.
  candidate,    ///< CANDIDATE (the PC back, or told of a newer epoch): stands until it wins.
  stepped_down, ///< An elected agent's master that saw a newer epoch: silent; the program drops it.
};

/// Spelling of a master role.
constexpr std::string_view to_string(MasterRole r) noexcept {
  switch (r) {
    case MasterRole::master: return "MASTER";
    case MasterRole::candidate: return "CANDIDATE";
    case MasterRole::stepped_down: return "STEPPED_DOWN";
  }
  return {};
}

/// Where the PC's election rules and an elected agent's master's differ (Election.tla: n = PC).
struct MasterPolicy {
  /// Owns the membership: StartElection sends a copy of it first (Teach), BecomeMaster moves it one
  /// step towards the fleet wanted (OneStep), and Reconfigure stands to publish the next step.
  bool reconfigures;
  /// A newer epoch ends its term for good (SteppedDown: its agent core votes and learns the
  /// membership, so ELECT and membership copies of a newer epoch are its business too; a newer
  /// master's LEADER gets its registry, HANDOVER); else it stands again (CANDIDATE).
  bool yields;
};
/// The PC (id 1): the fleet's membership is its; a newer epoch makes it stand again.
inline constexpr MasterPolicy kPcPolicy{true, false};
/// An agent that won an epoch: the membership it counted against stays; a newer epoch ends it.
inline constexpr MasterPolicy kElectedAgentPolicy{false, true};

/// The master node's Election.tla variables, the enabling conditions of its rules and their
/// transitions. @p Net (the Master core) sends: broadcast(type, params), send(peer, id, type,
/// params), now(); @p Reg (its Registry) lists the entries: map() of entries with `synced`.
class MasterElection {
 public:
  /// "No deadline".
  static constexpr Millis kNever = ~Millis{0};

  /// Election on or off (@p on), epoch @p e (0 counts as 1), master id @p self (the policy follows
  /// from it), the membership @p ids of epoch @p members_epoch (0: @p e), timers @p t.
  MasterElection(bool on, std::uint32_t e, std::uint16_t self_id, const std::vector<std::uint16_t>& ids,
                 std::uint32_t members_epoch, const Timers& t)
      : enabled(on), policy(self_id == kMasterId ? kPcPolicy : kElectedAgentPolicy), epoch(e == 0 ? 1 : e),
        self(self_id), members(ids.begin(), ids.end()), mepoch(members_epoch != 0 ? members_epoch : epoch),
        heartbeat_(t[Timer::leader_heartbeat]), candidate_(t[Timer::candidate]) {}

  // ------------------------------------------------------------ the master node's variables
  bool enabled;                     ///< Relay and election on (else Fleet.tla's master).
  MasterPolicy policy;              ///< The PC's rules or an elected agent's.
  MasterRole role = MasterRole::master;  ///< life
  std::uint32_t epoch;              ///< epoch
  std::uint16_t self;               ///< The master's id: 1 (PC) or the elected agent's.
  std::set<std::uint16_t> members;  ///< members[n]: the membership of epoch mepoch
  std::uint32_t mepoch;             ///< mepoch[n]
  std::set<std::uint16_t> votes;    ///< votes[n]
  std::set<std::uint16_t> handed;   ///< ids handed over (HANDOVER), wanted as members
  std::set<std::uint16_t> lost;     ///< ids declared lost (DropMember) since they last synced: not wanted
  std::uint64_t members_rev = 0;    ///< Moves whenever members, handed, lost or a synced entry change.
  Millis hb_at = kNever;            ///< The next LEADER (MASTER).
  Millis cand_at = kNever;          ///< The next StartElection (CANDIDATE).
  bool handed_over = false;         ///< This elected agent's master sent HANDOVER.

  // ------------------------------------------------------------ the fleet wanted

  /// A member of our membership, or handed over to us.
  bool known(std::uint16_t id) const { return members.count(id) != 0 || handed.count(id) != 0; }
  /// Election want: the membership and the members handed over but those declared lost
  /// (DropMember), and the agents registered and synced in @p reg. A walk of the registry, so built
  /// only when members_rev moved since the last build, not per datagram: at 10,000 agents a walk
  /// per datagram would make the master's cost per datagram grow with the fleet.
  template <class Reg>
  const std::set<std::uint16_t>& Want(const Reg& reg) const {
    if (want_built_ && want_rev_ == members_rev) return want_;
    want_.clear();
    for (std::uint16_t id : members)
      if (lost.count(id) == 0) want_.insert(id);
    for (std::uint16_t id : handed)
      if (lost.count(id) == 0) want_.insert(id);
    for (const auto& kv : reg.map())
      if (kv.second.synced) want_.insert(kv.first);
    want_moves_ = OneStep(members, want_) != members;
    want_rev_ = members_rev;
    want_built_ = true;
    return want_;
  }
  /// Election OneStep(L, w): L with one agent of w added (the lowest id) while L has fewer than
  /// kMaxMembership (Election MaxMembers: all one LEADER carries), else one agent not in w removed,
  /// never down to none; L when neither is possible. A full membership still sheds a lost agent.
  static std::set<std::uint16_t> OneStep(std::set<std::uint16_t> l, const std::set<std::uint16_t>& w) {
    if (l.size() < kMaxMembership)
      for (std::uint16_t id : w)
        if (l.count(id) == 0) {
          l.insert(id);
          return l;
        }
    for (std::uint16_t id : l)
      if (w.count(id) == 0 && l.size() > 1) {
        l.erase(id);
        return l;
      }
    return l;
  }
  /// LEADER's parameters: epoch @p e, leader @p leader (0 in a copy: no master claimed), and the
  /// membership of the master's epoch.
  std::vector<std::string> leader_params(std::uint32_t e, std::uint16_t leader) const {
    std::vector<std::string> p{std::to_string(e), std::to_string(leader)};
    for (std::uint16_t id : members) {
      if (p.size() == kMaxParams) break;
      p.push_back(std::to_string(id));
    }
    return p;
  }

  // ------------------------------------------------------------ timed rules

  /// Heartbeat is due at @p now (MASTER).
  bool HeartbeatOk(Millis now) const noexcept { return role == MasterRole::master && hb_at <= now; }
  /// Spec Heartbeat: LEADER(epoch, id, members...) broadcast every leader_heartbeat: the membership
  /// of the epoch, fixed for the whole epoch.
  template <class Net>
  void Heartbeat(Net& n) {
    hb_at = n.now() + heartbeat_;
    n.broadcast(MsgType::LEADER, leader_params(epoch, self));
  }

  /// StartElection is due at @p now (CANDIDATE, an epoch left to stand in: Election's epoch < MaxEpoch).
  bool StartElectionOk(Millis now) const noexcept {
    return role == MasterRole::candidate && EpochLeft() && cand_at <= now;
  }
  /// An epoch above this one exists (epochs are 32-bit on the wire).
  bool EpochLeft() const noexcept { return epoch < 0xFFFFFFFFu; }
  /// When StartElection is next due: never without an epoch left (no deadline the core cannot act on).
  Millis StandDeadline() const noexcept { return EpochLeft() ? cand_at : kNever; }
  /// Spec StartElection (the PC, CANDIDATE): epoch + 1, ELECT(epoch, 0, epoch of its membership)
  /// broadcast (a voter's floor rises to it); again after the candidate timeout without a majority.
  /// With a membership, a copy of it goes first (Election Teach): LEADER(mepoch, 0, members...)
  /// broadcast, so a voter that missed the LEADERs of that epoch learns the list (LearnMembers)
  /// and can grant (a voter grants the PC only if it knows a list at least as new: Knows).
  template <class Net>
  void StartElection(Net& n) {
    ++epoch;
    votes.clear();
    cand_at = n.now() + candidate_;
    if (policy.reconfigures && !members.empty()) n.broadcast(MsgType::LEADER, leader_params(mepoch, 0));
    n.broadcast(MsgType::ELECT, {std::to_string(epoch), "0", std::to_string(mepoch)});
  }

  // ------------------------------------------------------------ role steps

  /// A candidate that has stood since it published its membership (epoch newer than the list's:
  /// after Reconfigure the votes of its epoch still count until StartElection) holds the votes of a
  /// strict majority of it (QuorumOf); with none (a fresh PC: nobody can know a list) no vote is
  /// needed.
  bool BecomeMasterOk() const {
    return role == MasterRole::candidate && epoch > mepoch && (members.empty() || QuorumOf(votes, members, 0));
  }
  /// Spec BecomeMaster: master of the epoch; the PC's membership moves one step (OneStep) towards
  /// the fleet wanted, an elected agent's stays the one it counted against; LEADER at once.
  template <class Net, class Reg>
  void BecomeMaster(Net& n, const Reg& reg) {
    become_master();
    if (policy.reconfigures) members = OneStep(members, Want(reg));
    mepoch = epoch;
    ++members_rev;
    Heartbeat(n);
  }
  /// Election Reconfigure's guard: the PC as MASTER whose wanted fleet differs from the membership
  /// of its epoch by a step OneStep can take. An elected agent's master never changes its
  /// membership (node.hpp). The list stops growing at kMaxMembership, all that one LEADER carries
  /// (and the state files keep): agents beyond it follow and obey but never vote, and a full list
  /// still sheds an agent declared lost (docs/election.md section 6).
  template <class Reg>
  bool ReconfigureOk(const Reg& reg) const {
    if (!enabled || !policy.reconfigures || role != MasterRole::master) return false;
    Want(reg);
    return want_moves_;
  }
  /// Spec Reconfigure: the PC stands in the next epoch to publish the next step.
  void Reconfigure(Millis now) { become_candidate(now); }
  /// Spec DropMember (part of MasterTick's drop: the PC declares agent @p id lost): it is no longer
  /// wanted (Want), so Reconfigure removes it from the membership, one agent per epoch, until it
  /// syncs again. Without it a lost agent stayed a member: the fleet needed a majority without it.
  void DropMember(std::uint16_t id) {
    lost.insert(id);
    ++members_rev;
  }
  /// Agent @p id (re)joined the registry synced: wanted again.
  void Synced(std::uint16_t id) { lost.erase(id); }

  // ------------------------------------------------------------ receive rules

  /// True when an Election rule of the master takes datagrams of type @p t.
  static bool Ruled(MsgType t) noexcept {
    return t == MsgType::ELECT || t == MsgType::VOTE || t == MsgType::LEADER || t == MsgType::EPOCH_STALE ||
           t == MsgType::HANDOVER;
  }
  /// The rule that takes @p m (Ruled(m.type)), or Ignore when none is enabled. LEADER has two,
  /// whose guards exclude each other.
  Action Choose(const Message& m) const {
    switch (m.type) {
      case MsgType::ELECT: return HandleElectOk(m) ? Action::HandleElect : Action::Ignore;
      case MsgType::VOTE: return HandleVoteOk(m) ? Action::HandleVote : Action::Ignore;
      case MsgType::LEADER:
        if (HandleHeartbeatOk(m)) return Action::HandleHeartbeat;
        return LearnMembersOk(m) ? Action::LearnMembers : Action::Ignore;
      case MsgType::EPOCH_STALE: return HandleStaleOk(m) ? Action::HandleStale : Action::Ignore;
      case MsgType::HANDOVER: return MasterHandoverOk(m) ? Action::MasterHandover : Action::Ignore;
      default: return Action::Ignore;
    }
  }
  /// Runs rule @p a that Choose() picked for @p m from @p from.
  template <class Net, class Reg>
  void Run(Action a, const Message& m, Peer from, Net& n, const Reg& reg) {
    switch (a) {
      case Action::HandleElect: HandleElect(m); break;
      case Action::HandleVote: HandleVote(m); break;
      case Action::HandleHeartbeat: HandleHeartbeat(m, from, n, reg); break;
      case Action::LearnMembers: LearnMembers(m, n.now()); break;
      case Action::HandleStale: HandleStale(m, n.now()); break;
      case Action::MasterHandover: MasterHandover(m); break;
      default: break;
    }
  }

  /// ELECT of a newer epoch, to a master that yields (the PC learns epochs from EPOCH_STALE).
  bool HandleElectOk(const Message& m) const {
    const auto e = m.param_u32(0);
    return policy.yields && role != MasterRole::stepped_down && e && *e > epoch;
  }
  /// Spec HandleElect, the master node's part: an elected agent's master steps down on a newer
  /// epoch (its agent core votes).
  void HandleElect(const Message& m) {
    epoch = *m.param_u32(0);
    become_stepped_down();
  }

  /// A candidate's VOTE for us in our epoch, from a member not counted yet.
  bool HandleVoteOk(const Message& m) const {
    const auto e = m.param_u32(0);
    const auto c = m.param_u16(1);
    return role == MasterRole::candidate && m.receiver == self && e && c && *e == epoch && *c == self &&
           members.count(m.sender) != 0 && votes.count(m.sender) == 0;
  }
  /// Spec HandleVote: one more vote.
  void HandleVote(const Message& m) { votes.insert(m.sender); }

  /// A master's LEADER (it names its sender as leader: a copy, leader 0, claims no master and is
  /// the agent core's, LearnMembers) of an older epoch (while we have not stepped down: it is
  /// told), a newer one, or our own epoch's other master while we yield and have not handed over.
  bool HandleHeartbeatOk(const Message& m) const {
    const auto e = m.param_u32(0);
    if (!e || m.param_u16(1) != m.sender) return false;
    if (*e < epoch) return role != MasterRole::stepped_down;
    return *e > epoch || (role != MasterRole::master && policy.yields && !handed_over);
  }
  /// Spec HandleHeartbeat, the master node's part: an older master's LEADER is answered
  /// EPOCH_STALE; a newer one ends our term: the PC stands again above it, an elected agent hands
  /// its registry over (HANDOVER) and steps down.
  template <class Net, class Reg>
  void HandleHeartbeat(const Message& m, Peer from, Net& n, const Reg& reg) {
    const std::uint32_t e = *m.param_u32(0);
    if (e < epoch) {
      n.send(from, m.sender, MsgType::EPOCH_STALE, {std::to_string(epoch)});
      return;
    }
    epoch = e;
    if (!policy.yields) {
      votes.clear();  // HandleStaleNext's rule: the votes of the older epoch do not count in e
      become_candidate(n.now());
      return;
    }
    if (!handed_over) {
      std::vector<std::string> p{std::to_string(epoch)};
      for (std::uint16_t id : Want(reg)) {
        if (p.size() == kMaxParams) break;
        p.push_back(std::to_string(id));
      }
      n.send(from, m.sender, MsgType::HANDOVER, p);
      handed_over = true;
    }
    become_stepped_down();
  }

  /// A copy of a LEADER (leader 0: no master claimed; the PC's broadcast as it stands, or a peer's
  /// to us) of an epoch newer than ours, to a master that yields and has not stepped down.
  bool LearnMembersOk(const Message& m) const {
    const auto e = m.param_u32(0);
    return policy.yields && role != MasterRole::stepped_down && membership_copy(m, self) && e && *e > epoch;
  }
  /// Spec LearnMembers, the master node's part: Election's LearnMembersNext of a newer epoch is
  /// HandleStale's rule (the node steps down; the list is its agent core's). No HANDOVER: a copy
  /// names no master to hand the registry to.
  void LearnMembers(const Message& m, Millis now) { HandleStale(m, now); }

  /// EPOCH_STALE to us naming a newer epoch.
  bool HandleStaleOk(const Message& m) const {
    const auto e = m.param_u32(0);
    return m.receiver == self && e && *e > epoch;
  }
  /// Spec HandleStale: a newer epoch exists: the PC stands again (CANDIDATE), an elected agent's
  /// master steps down. Votes of the older epoch do not count in the newer one (counted, they
  /// would let the PC win the newer epoch: a TLC counterexample).
  void HandleStale(const Message& m, Millis now) {
    epoch = *m.param_u32(0);
    votes.clear();
    if (policy.yields)
      become_stepped_down();
    else
      become_candidate(now);
  }

  /// HANDOVER to us (MASTER) from the master of an epoch not newer than ours.
  bool MasterHandoverOk(const Message& m) const {
    const auto e = m.param_u32(0);
    return role == MasterRole::master && m.receiver == self && e && *e <= epoch;
  }
  /// HANDOVER(epoch, id...) from the elected agent we replace: its fleet joins the fleet we want
  /// (Want; the membership follows one step per epoch, Reconfigure).
  void MasterHandover(const Message& m) {
    for (std::size_t i = 1; i < m.param_count(); ++i)
      if (const auto id = m.param_u16(i)) {
        if (is_assigned_id(*id) && *id != self && (handed.insert(*id).second || lost.erase(*id) != 0))
          ++members_rev;  // alive in the fleet handed over: no longer lost
      }
  }

  // ------------------------------------------------------------ role changes (raft's become*)
  // Each in one place: the timers of the role left are cleared.

  void become_master() {
    role = MasterRole::master;
    cand_at = kNever;
  }
  void become_candidate(Millis now) {
    role = MasterRole::candidate;
    hb_at = kNever;
    cand_at = now;  // stands at once
  }
  void become_stepped_down() {
    role = MasterRole::stepped_down;
    hb_at = cand_at = kNever;
  }

 private:
  Millis heartbeat_, candidate_;  // leader_heartbeat, candidate (Timers)
  // Want()'s cache: the set, whether OneStep moves members towards it, the members_rev it is of.
  mutable std::set<std::uint16_t> want_;
  mutable bool want_moves_ = false, want_built_ = false;
  mutable std::uint64_t want_rev_ = 0;
};

}  // namespace ev3proto
