// The C++ forms of the spec's invariants the core fuzz targets check after every step: Agent.tla's on
// an agent core, Master.tla's on a master core (fuzz_agent, fuzz_master, fuzz_node).
#pragma once

#include <map>

#include "ev3proto/agent.hpp"
#include "ev3proto/durable.hpp"
#include "ev3proto/master.hpp"
#include "fuzz_input.hpp"

namespace fuzzin {

/// Agent.tla's invariants on agent core @p a at @p now, with timers @p t.
template <typename Core>
void check_agent(const Core& a, ev3proto::Millis now, const ev3proto::Timers& t) {
  using ev3proto::State;
  if (a.led() != ev3proto::led_of(a.state())) violation("LedInv");
  if (a.motors() && a.state() != State::WORKING) violation("BehaviourOnlyInWorkingInv");
  if (a.motors() && a.wait() != ev3proto::Wait::NONE) violation("MotorsOnlyWhileRunningInv");
  if (a.state() == State::WORKING && now - a.last_heard() > t[ev3proto::Timer::loss])
    violation("NoUnsupervisedMotionInv");
  if (a.state() == State::WORKING && a.behaviour().name.empty()) violation("WorkingLoadedInv");
  if (a.next_deadline() < now) violation("a deadline left behind");
  // Reports.tla BufferInv: the marker lies below the reports held, at most the bound held.
  const auto& r = a.reports();
  if (!(r.lo() - 1 <= r.mk() && r.mk() <= r.made() && r.held() <= Core::ReportsType::kSlots))
    violation("BufferInv (reports)");
}

/// Master.tla's invariants on master core @p m's registry. One entry per endpoint (RegistryInv)
/// only without the election: with it, agents relayed by one peer are reached at that peer's
/// endpoint, and an entry follows its agent to wherever its datagrams come from (Election.tla reads
/// the route).
template <typename Core>
void check_master(const Core& m, bool election) {
  std::map<ev3proto::Peer, std::uint16_t> peers;
  for (const auto& [id, x] : m.registry()) {
    if (x.id != id) violation("an entry under another id");
    if (!election && !peers.emplace(x.peer, id).second) violation("RegistryInv");
    if (id >= m.next_id()) violation("IdsInv");
    if (x.pending && !ev3proto::msgid_newer(m.next_msgid(), x.mid)) violation("MidInv");
    if (x.pending && x.synced && x.queue.empty()) violation("PendingInv");
  }
  // Reports.tla's record: each agent's numbers first..last are each a report, a drop or a skip
  // (InOrderInv, NoDuplicateInv as counts), and a gap lies beyond the record.
  for (const auto& [id, r] : m.report_records()) {
    if (r.next == 0) continue;
    if (r.first == 0 || r.next < r.first) violation("a record of reports without its start");
    if (std::uint64_t{r.reports} + r.dropped + r.skipped != std::uint64_t{r.next} - r.first) violation("InOrderInv (reports)");
    if (r.ahead != 0 && r.ahead <= r.next) violation("a gap inside the record of reports");
  }
}

/// What a master would write to its state file reads back (the file a restart reads: durable.hpp's
/// own check).
inline void check_master_durable_text(const ev3proto::MasterDurable& d) {
  ev3proto::MasterDurable back;
  ev3proto::DurableError err;
  if (!ev3proto::parse_master_durable(ev3proto::durable_text(d).view(), back, err))
    violation("a master state file that does not read back");
}

/// A master's durable state between two steps: the epoch never goes back, and it reads back.
inline void check_master_durable(const ev3proto::MasterDurable& before, const ev3proto::MasterDurable& now) {
  if (now.epoch < before.epoch) violation("the master's epoch went back");
  check_master_durable_text(now);
}

/// The same of an agent's durable state (its state file).
inline void check_agent_durable_text(const ev3proto::Durable& d) {
  ev3proto::Durable back;
  ev3proto::DurableError err;
  if (!ev3proto::parse_durable(ev3proto::durable_text(d).view(), back, err))
    violation("an agent state file that does not read back");
}

}  // namespace fuzzin
