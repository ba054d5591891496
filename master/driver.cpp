// ev3-master --driver: the master core on a virtual clock, no sockets; NDJSON on stdin/stdout, one
// output line per input line (docs/driver.md, "Master driver"). Logs go to stderr. The conformance
// runner (conformance/, `ev3-conformance replay --model master`) drives it with MCMaster's edges.
#include "driver.hpp"

#include <cstdio>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <ev3proto/master.hpp>
#include <ev3proto/json.hpp>
#include <ev3proto/trace.hpp>
#include <ev3proto/wire.hpp>

#include "ev3prog/driver_json.hpp"
#include "ev3prog/program.hpp"

namespace ev3master {
namespace {

using ev3prog::Json;
using ev3proto::json_string;
using ev3proto::Millis;

struct MasterSink;
using Core = ev3proto::Master<MasterSink>;

/// The master's variables (MasterLogic ms: reg, nextId, msgid; desired as the spec names it,
/// UNKNOWN when not known) plus what the spec abstracts from (heard, state, via): JSON.
std::string vars_json(const Core& m) {
  std::string s = "{\"nextId\":" + std::to_string(m.next_id()) + ",\"msgid\":" + std::to_string(m.next_msgid()) +
                  ",\"reg\":[";
  bool first = true;
  for (const auto& kv : m.registry()) {
    const ev3proto::RegistryEntry& e = kv.second;
    if (!first) s += ',';
    first = false;
    s += "{\"ann\":" + std::to_string(e.ann) + ",\"id\":" + std::to_string(e.id) + ",\"ep\":" +
         std::to_string(e.peer) + ",\"synced\":" + (e.synced ? "true" : "false") + ",\"pending\":" +
         (e.pending ? "true" : "false") + ",\"mid\":" + std::to_string(e.mid) + ",\"resends\":" +
         std::to_string(e.resends) + ",\"queue\":[";
    bool q1 = true;
    for (const ev3proto::Command& c : e.queue) {
      if (!q1) s += ',';
      q1 = false;
      s += "{\"type\":\"" + std::string(to_string(c.type)) + "\",\"name\":";
      json_string(s, c.type == ev3proto::MsgType::BEHAVIOUR ? std::string_view(c.name) : std::string_view("NONE"));
      s += "}";
    }
    s += "],\"beh\":";
    json_string(s, e.behaviour.empty() ? std::string_view("NONE") : std::string_view(e.behaviour));
    s += ",\"desired\":\"" +
         (e.desired_known ? std::string(to_string(e.desired)) : std::string("UNKNOWN")) + "\"";
    s += ",\"heard\":" + std::to_string(e.heard) + ",\"quiet_ms\":" + std::to_string(m.now() - e.heard) +
         ",\"hi\":" + std::to_string(e.last_msgid) + ",\"state\":\"" +
         (e.has_state ? std::string(to_string(e.state)) : std::string("NONE")) + "\",\"via\":" +
         std::to_string(e.via) + "}";
  }
  return s + "]}";
}

std::string ids_json(const std::vector<std::uint16_t>& ids) {
  std::string s = "[";
  for (std::size_t i = 0; i < ids.size(); ++i) s += (i ? "," : "") + std::to_string(ids[i]);
  return s + "]";
}

/// The master node's Election.tla variables after the input: life (MASTER, CANDIDATE,
/// STEPPED_DOWN), epoch, votes, members / mepoch (the membership of its epoch), want (want()),
/// handed_over (HANDOVER sent), self (its id).
std::string election_json(const Core& m) {
  return "{\"life\":\"" + std::string(to_string(m.role())) + "\",\"self\":" + std::to_string(m.self_id()) +
         ",\"epoch\":" + std::to_string(m.epoch()) + ",\"votes\":" + ids_json(m.votes()) +
         ",\"members\":" + ids_json(m.members()) + ",\"mepoch\":" + std::to_string(m.members_epoch()) +
         ",\"want\":" + ids_json(m.want()) + ",\"handed_over\":" + (m.handed_over() ? "true" : "false") + "}";
}

/// Trace sink: every spec action with its message and the variables after it.
struct MasterSink {
  static constexpr bool enabled = true;
  const Core* core = nullptr;  // the core the records come from (for the variables after)
  std::vector<std::string> actions;
  std::FILE* trace = nullptr;
  void record(const ev3proto::MasterTraceRecord& r) {
    std::string s = "{\"action\":\"" + std::string(to_string(r.action)) + "\",\"args\":{";
    if (!r.msg.empty()) {
      s += "\"msg\":";
      json_string(s, r.msg);
    }
    s += "},\"now\":" + std::to_string(r.now) + ",\"next_msgid\":" + std::to_string(r.msgid_after);
    if (core != nullptr) s += ",\"vars\":" + vars_json(*core);
    s += "}";
    actions.push_back(std::move(s));
    if (trace != nullptr) {
      const std::string line = ev3proto::to_ndjson(r, "master");
      std::fwrite(line.data(), 1, line.size(), trace);
      std::fputc('\n', trace);
    }
  }
};

std::optional<ev3proto::MsgType> command_type(const std::string& n) {
  using ev3proto::MsgType;
  const MsgType all[] = {MsgType::BEHAVIOUR, MsgType::START,   MsgType::STOP,     MsgType::PAUSE,
                         MsgType::RESUME,    MsgType::STANDBY, MsgType::CONTINUE, MsgType::RESTART};
  for (MsgType t : all)
    if (n == to_string(t)) return t;
  return std::nullopt;
}

const char* event_kind(ev3proto::OperatorEvent::Kind k) { return to_string(k).data(); }

class Driver {
 public:
  explicit Driver(std::FILE* trace) { sink_.trace = trace; }

  int run() {
    return ev3prog::run_driver_lines(sink_.trace, seq_, [this](const std::string& line) { return handle(line); });
  }

  // Below: what ev3prog::dispatch_input() asks of a driver (configure() among it), then output().
  std::string error(const std::string& msg) { return ev3prog::driver_error("ev3-master --driver", seq_, msg); }

  bool configure(const Json& in, std::string& err) {
    ev3proto::MasterConfig c;
    const Json& t = in["timers"];
    if (t.has("resend")) c.timers.set(ev3proto::Timer::resend, static_cast<Millis>(t["resend"].num(1)));
    if (t.has("drop")) c.timers.set(ev3proto::Timer::drop, static_cast<Millis>(t["drop"].num(1)));
    if (c.timers[ev3proto::Timer::resend] == 0 || c.timers[ev3proto::Timer::drop] == 0) {
      err = "timers: resend and drop must be > 0";
      return false;
    }
    c.max_resends = static_cast<std::uint32_t>(in["max_resends"].num(10));
    c.next_id = static_cast<std::uint16_t>(in["next_id"].num(ev3proto::kFirstAssignedId));
    c.next_msgid = static_cast<std::uint32_t>(in["next_msgid"].num(1));
    if (!configure_election(in, c, err)) return false;
    const Millis now = static_cast<Millis>(in["now"].num(0));
    core_.emplace(c, now, &sink_);
    sink_.core = &*core_;
    snaps_.clear();
    std::fprintf(stderr, "ev3-master --driver: configured (resend %llu ms, drop %llu ms, max resends %u, now %llu)\n",
                 static_cast<unsigned long long>(c.timers[ev3proto::Timer::resend]),
                 static_cast<unsigned long long>(c.timers[ev3proto::Timer::drop]), c.max_resends,
                 static_cast<unsigned long long>(now));
    return true;
  }

  /// config's "election" object (Election.tla's master node, docs/driver.md "Master driver"): the PC
  /// (self_id 1: epoch, membership and candidate as ev3-master restores them from its state file) or an
  /// elected agent's Master core (self_id > 1: MasterConfig::for_elected_agent, as node.hpp runs it).
  /// timers.leader_heartbeat and timers.candidate are the election's periods.
  static bool configure_election(const Json& in, ev3proto::MasterConfig& c, std::string& err) {
    const Json& t = in["timers"];
    if (t.has("leader_heartbeat"))
      c.timers.set(ev3proto::Timer::leader_heartbeat, static_cast<Millis>(t["leader_heartbeat"].num(1)));
    if (t.has("candidate")) c.timers.set(ev3proto::Timer::candidate, static_cast<Millis>(t["candidate"].num(1)));
    const Json& el = in["election"];
    if (!el["enabled"].boolean(false)) return true;
    std::vector<std::uint16_t> members;
    if (el.has("members")) {
      if (el["members"].kind != Json::Kind::array) {
        err = "election: members must be an array of agent ids";
        return false;
      }
      for (const Json& m : el["members"].a) {
        const long long id = m.num(0);
        if (!ev3proto::is_assigned_id(static_cast<std::uint16_t>(id)) || id > 0xffff) {
          err = "election: member " + std::to_string(id) + " is not an agent id";
          return false;
        }
        members.push_back(static_cast<std::uint16_t>(id));
      }
    }
    const auto epoch = static_cast<std::uint32_t>(el["epoch"].num(1));
    const long long self = el["self_id"].num(ev3proto::kMasterId);
    if (self != ev3proto::kMasterId) {
      if (self > 0xffff || !ev3proto::is_assigned_id(static_cast<std::uint16_t>(self))) {
        err = "election: self_id " + std::to_string(self) + " is neither 1 (the PC) nor an agent id";
        return false;
      }
      c = ev3proto::MasterConfig::for_elected_agent(c.timers, static_cast<std::uint16_t>(self), epoch, members);
      return true;
    }
    c.election = true;
    c.epoch = epoch;
    c.members = members;
    c.members_epoch = static_cast<std::uint32_t>(el["members_epoch"].num(0));
    c.candidate = el["candidate"].boolean(false);
    return true;
  }

  std::string handle(const std::string& line) { return ev3prog::dispatch_input(*this, line); }

  void clear_actions() { sink_.actions.clear(); }
  bool has_core() const { return core_.has_value(); }
  Millis core_now() const { return core_->now(); }
  void core_advance(Millis to) { core_->advance(to); }
  void core_recv(const std::string& bytes, const Json& in, Millis now) {
    core_->handle_datagram(bytes, static_cast<ev3proto::Peer>(in["from"].num(1)), now);
  }
  /// Every input of the master needs a core.
  bool early(const std::string&, const Json&, std::string&) { return false; }
  std::string own(const std::string& type, const Json& in, Millis now) {
    if (type == "command") {
      const auto t = command_type(in["command"].str());
      if (!t) return error("unknown command '" + in["command"].str() + "' (BEHAVIOUR START STOP PAUSE RESUME STANDBY CONTINUE RESTART)");
      ev3proto::Command c = ev3proto::Command::simple(*t);
      if (*t == ev3proto::MsgType::BEHAVIOUR) {
        std::vector<std::string> args;
        for (const Json& a : in["args"].a) args.push_back(a.str());
        c = ev3proto::Command::assign(in["behaviour"].str("wait"), std::move(args));
      }
      core_->command(static_cast<std::uint16_t>(in["agent"].num(0)), c, now);
      return output(true);
    }
    if (type == "save") {
      snaps_.insert_or_assign(in["slot"].num(), *core_);
      return output(true);
    }
    if (type == "restore") {
      auto it = snaps_.find(in["slot"].num());
      if (it == snaps_.end()) return error("no snapshot in that slot");
      *core_ = it->second;
      sink_.actions.clear();
      ev3proto::MasterTransmit t;
      while (core_->poll_transmit(t)) {
      }
      ev3proto::OperatorEvent e;
      while (core_->poll_event(e)) {
      }
      return output(true);
    }
    return error("unknown input type '" + type + "'");
  }

  std::string output(bool taken) {
    if (!core_) return ev3prog::output_start(seq_, taken) + "}";
    std::string s = ev3prog::output_start(seq_, taken, core_->now(), sink_.actions) + ",\"sent\":[";
    ev3proto::MasterTransmit t;
    bool first = true;
    while (core_->poll_transmit(t)) {
      if (!first) s += ',';
      first = false;
      s += std::string("{\"to\":\"") + (t.dest == ev3proto::Dest::broadcast ? "broadcast" : "peer") +
           "\",\"peer\":" + std::to_string(t.peer) + ",\"text\":";
      json_string(s, t.bytes);
      s += ",\"hex\":\"" + ev3prog::hex(t.bytes) + "\"}";
    }
    s += "],\"events\":[";
    ev3proto::OperatorEvent e;
    first = true;
    while (core_->poll_event(e)) {
      if (!first) s += ',';
      first = false;
      s += std::string("{\"kind\":\"") + event_kind(e.kind) + "\",\"agent\":" + std::to_string(e.agent) +
           ",\"command\":\"" + std::string(to_string(e.command)) + "\",\"text\":";
      json_string(s, e.text);
      s += "}";
    }
    const Millis d = core_->next_deadline();
    s += "],\"deadline\":" + (d == Core::kNever ? std::string("null") : std::to_string(d));
    s += ",\"vars\":" + vars_json(*core_);
    if (core_->election()) s += ",\"election\":" + election_json(*core_);
    return s + "}";
  }

 private:
  MasterSink sink_;
  std::optional<Core> core_;
  std::map<long long, Core> snaps_;
  unsigned long long seq_ = 0;
};

}  // namespace

int run_driver(int argc, char** argv) {
  return ev3prog::driver_main<Driver>(argc, argv, "ev3-master", "master", "config, recv, command, advance, save, restore");
}

}  // namespace ev3master
