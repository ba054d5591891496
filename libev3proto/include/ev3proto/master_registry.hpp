/// @file master_registry.hpp
/// @brief The master's registry (MasterLogic.tla's reg): one entry per agent, found by id, by the id
///        it announced and by its peer without a walk; the operator commands queued in an entry;
///        and the window of datagrams already taken (MasterConfig::drop_copies). The PC may
///        allocate: std::map, std::set, std::vector.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core.hpp"
#include "dedupe.hpp"
#include "messages.hpp"

namespace ev3proto {

/// An operator command for one agent: a master command type and, for BEHAVIOUR, name and args.
struct Command {
  MsgType type = MsgType::START;  ///< BEHAVIOUR, START, STOP, PAUSE, RESUME, STANDBY, CONTINUE, RESTART.
  std::string name;               ///< BEHAVIOUR: behaviour name.
  std::vector<std::string> args;  ///< BEHAVIOUR: key=value arguments.
  std::uint32_t tag = 0;          ///< The caller's number for the command, given back in the
                                  ///< OperatorEvent of its answer (0: one the core made itself).

  /// BEHAVIOUR(name, args...).
  static Command assign(std::string behaviour, std::vector<std::string> arguments = {}) {
    return Command{MsgType::BEHAVIOUR, std::move(behaviour), std::move(arguments)};
  }
  /// A command without params (START, STOP, ...).
  static Command simple(MsgType t) { return Command{t, {}, {}}; }
};

/// True for the message types an operator may send as a command.
constexpr bool is_command(MsgType t) noexcept {
  return t >= MsgType::BEHAVIOUR && t <= MsgType::RESTART;
}

/// MasterConfig::drop_copies: the (sender, msgid) pairs taken lately. On the heap, and only when
/// asked for: a Master is copied by the conformance driver's snapshots.
class CopyWindow {
 public:
  /// A window when @p on, else nothing (every datagram is a first time).
  explicit CopyWindow(bool on) : w_(on ? std::make_unique<Window>() : nullptr) {}
  CopyWindow(const CopyWindow& o) : w_(o.w_ ? std::make_unique<Window>(*o.w_) : nullptr) {}
  CopyWindow& operator=(const CopyWindow& o) {
    w_ = o.w_ ? std::make_unique<Window>(*o.w_) : nullptr;
    return *this;
  }
  CopyWindow(CopyWindow&&) noexcept = default;
  CopyWindow& operator=(CopyWindow&&) noexcept = default;
  ~CopyWindow() = default;

  /// True when (sender, msgid) was not taken lately (and remembers it), or there is no window.
  bool first_time(std::uint16_t sender, std::uint32_t msgid) {
    return w_ == nullptr || w_->first_time(sender, msgid);
  }

 private:
  using Window = DedupeWindow<4096>;
  std::unique_ptr<Window> w_;
};

/// One registry entry (MasterLogic EntryType; spec field names in brackets), plus what the operator
/// needs.
/// Aligned to a cache line, with what every datagram reads in its first 64 bytes (ids, flags, times,
/// the queue's bounds): at 10,000 agents an entry is rarely in cache when its agent's PING comes, and
/// one line costs less than the two or three an unaligned entry spans (docs/benchmarks.md).
struct alignas(64) RegistryEntry {
  std::uint16_t id = 0;         ///< [id] Assigned id.
  std::uint16_t ann = 0;        ///< [ann] Announced id (temporary, or the old id of a PANIC agent).
  Peer peer = 0;                ///< [ep] Where the agent is.
  bool synced = false;          ///< [synced] The agent acknowledged MASTER.
  bool pending = false;         ///< [pending] A command (or MASTER while !synced) waits for its answer.
  bool has_state = false;       ///< A PING reported @c state.
  AgentState state = AgentState::IDLE; ///< State from the last PING.
  AgentState desired = AgentState::ACTIVE; ///< [desired] What the operator last asked (desired_after).
  bool desired_known = true;    ///< [desired = UNKNOWN] False after a refused command that no queued
                                ///< command overrides, and for an entry adopted by an elected master:
                                ///< no reconcile until the operator's next desired-setting command.
  std::uint16_t via = 0;        ///< The relay this agent is reached through (0 = direct; RELAY_ROUTE).
  /// [hi] Newest msgid heard from the agent, in serial-number order (msgid_newer, as the agent
  /// orders the master's msgids): an agent's msgids may wrap from 4294967295 to 0. MasterLogic.tla
  /// compares msgids with > within small bounds, where the two orders agree.
  std::uint32_t last_msgid = 0;
  std::uint32_t mid = 0;        ///< [mid] msgid of the pending datagram.
  std::uint32_t resends = 0;    ///< [resends] Resends of the pending command (MASTER's are not counted).
  Millis heard = 0;             ///< Last heard ([quiet] = now - heard).
  Millis sent_at = 0;           ///< When it was last sent.
  std::vector<Command> queue;   ///< [queue] Operator commands; the front one is pending once synced
                                ///< (a few at most; empty, it takes no memory).
  std::string behaviour;        ///< [beh] Behaviour the agent acknowledged last ("" = NONE).
  std::vector<std::string> behaviour_args; ///< Its arguments (reconcile sends them again).
  std::string model;            ///< The model it announced in AGENT ("A"; "" when it registered by PANIC).
  std::vector<std::string> devices; ///< The devices of its model it announced in AGENT ("left motor", ...).

  /// "MASTER" while not synced, the pending command's name, or "DONE" (for displays).
  std::string_view job() const noexcept {
    if (!synced) return "MASTER";
    if (pending && !queue.empty()) return to_string(queue.front().type);
    return "DONE";
  }
};

/// The master's registry: the entries by assigned id in a std::map (in order of id, as the spec's
/// records and the operator's table list them), and what finds an entry without walking them: a
/// flat index id -> entry, and ordered sets (announced id, id) and (peer, id). An entry's id, ann
/// and peer change only through this class.
class Registry {
 public:
  /// The entries by id.
  using Map = std::map<std::uint16_t, RegistryEntry>;

  Registry() = default;
  /// A copy (the conformance driver's snapshots): the index points into the copy's own entries.
  Registry(const Registry& o) : map_(o.map_), by_ann_(o.by_ann_), by_peer_(o.by_peer_) { reindex(); }
  Registry& operator=(const Registry& o) {
    if (this != &o) {
      map_ = o.map_;
      by_ann_ = o.by_ann_;
      by_peer_ = o.by_peer_;
      reindex();
    }
    return *this;
  }
  Registry(Registry&&) noexcept = default;  // a std::map's entries move with it: the index stays valid
  Registry& operator=(Registry&&) noexcept = default;
  ~Registry() = default;

  /// The entries.
  const Map& map() const noexcept { return map_; }
  /// The entries, to change what they hold (not their id, ann or peer).
  Map::iterator begin() noexcept { return map_.begin(); }
  Map::iterator end() noexcept { return map_.end(); }

  /// Entry @p id, or nullptr: O(1).
  RegistryEntry* find(std::uint16_t id) noexcept { return id < index_.size() ? index_[id] : nullptr; }
  const RegistryEntry* find(std::uint16_t id) const noexcept { return id < index_.size() ? index_[id] : nullptr; }
  /// True when @p id is registered.
  bool contains(std::uint16_t id) const noexcept { return find(id) != nullptr; }

  /// Adds @p e (its id not registered); returns it.
  RegistryEntry& insert(RegistryEntry e) {
    const std::uint16_t id = e.id;
    RegistryEntry& r = map_.emplace(id, std::move(e)).first->second;
    if (id >= index_.size()) index_.resize(std::size_t{id} + 1, nullptr);
    index_[id] = &r;
    by_ann_.insert({r.ann, id});
    by_peer_.insert({r.peer, id});
    return r;
  }
  /// Removes entry @p id (if registered).
  void erase(std::uint16_t id) {
    RegistryEntry* e = find(id);
    if (e == nullptr) return;
    by_ann_.erase({e->ann, id});
    by_peer_.erase({e->peer, id});
    index_[id] = nullptr;
    map_.erase(id);
  }
  /// Entry @p e now announces @p ann.
  void set_ann(RegistryEntry& e, std::uint16_t ann) {
    by_ann_.erase({e.ann, e.id});
    e.ann = ann;
    by_ann_.insert({ann, e.id});
  }
  /// Entry @p e is now at @p p.
  void set_peer(RegistryEntry& e, Peer p) {
    by_peer_.erase({e.peer, e.id});
    e.peer = p;
    by_peer_.insert({p, e.id});
  }

  /// Spec Known(reg, s): the ids of the entries whose announced or assigned id is s, in order.
  std::vector<std::uint16_t> known(std::uint16_t s) const {
    std::vector<std::uint16_t> k;
    for (auto it = by_ann_.lower_bound({s, 0}); it != by_ann_.end() && it->first == s; ++it)
      k.push_back(it->second);
    if (contains(s) && !std::binary_search(k.begin(), k.end(), s))
      k.insert(std::lower_bound(k.begin(), k.end(), s), s);
    return k;
  }
  /// The lowest id of an entry at @p p (0: none).
  std::uint16_t first_at(Peer p) const {
    const auto it = by_peer_.lower_bound({p, 0});
    return it != by_peer_.end() && it->first == p ? it->second : 0;
  }

 private:
  void reindex() {
    index_.assign(map_.empty() ? 0 : std::size_t{map_.rbegin()->first} + 1, nullptr);
    for (auto& kv : map_) index_[kv.first] = &kv.second;
  }

  Map map_;
  std::vector<RegistryEntry*> index_;                         // by id; up to the largest id held
  std::set<std::pair<std::uint16_t, std::uint16_t>> by_ann_;  // (ann, id)
  std::set<std::pair<Peer, std::uint16_t>> by_peer_;          // (peer, id)
};

}  // namespace ev3proto
