// ev3-reports-driver: the library's reliable reports (reports.hpp: an agent's ReportBuffer, a
// master's ReportRecord and PCTake; record.hpp: the PC's record file) driven one spec step at a
// time, no sockets, no clock: NDJSON on stdin, one NDJSON line on stdout per input line
// (docs/driver.md "Reports driver"). `ev3-conformance replay --model reports` replays every edge of
// MCReportsReplay's state graph (spec/tla/Reports.tla) against it.
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <ev3proto/json.hpp>
#include <ev3proto/record.hpp>
#include <ev3proto/reports.hpp>

#include "ev3prog/driver_json.hpp"

namespace {

using ev3prog::Json;
using ev3proto::ReportRecord;
using ev3proto::ReportTaken;

constexpr const char* kProgram = "ev3-reports-driver";
constexpr const char* kInputs = "config, make, send, take_ack, new_master, take, ack, crash, check, save, restore";

// The buffer's compiled bound is small (the driver copies it at every save); `config` sets the bound
// a model uses below it at run time, as ev3-agent --report-buffer does.
using Buffer = ev3proto::ReportBuffer<64, 4096>;

/// Everything the driver holds: each agent's buffer, the PC's records and its record file, and the
/// interim master's records (one interim master: Reports.tla's "im").
struct World {
  std::size_t cap = 64;
  std::map<std::uint16_t, Buffer> agents;
  std::map<std::uint16_t, ReportRecord> pc, im;
  std::string file;  // the PC's record file (record.hpp lines), appended as ev3-master --record does
};

const char* taken_name(ReportTaken t) {
  switch (t) {
    case ReportTaken::stored: return "stored";
    case ReportTaken::dropped: return "dropped";
    case ReportTaken::copy: return "copy";
    case ReportTaken::ahead: return "ahead";
    case ReportTaken::invalid: return "invalid";
  }
  return "?";
}

std::string records_json(const std::map<std::uint16_t, ReportRecord>& rs) {
  std::string s = "{";
  bool first = true;
  for (const auto& [id, r] : rs) {
    if (!first) s += ',';
    first = false;
    s += "\"" + std::to_string(id) + "\":{\"first\":" + std::to_string(r.first) + ",\"next\":" + std::to_string(r.next) +
         ",\"stored\":" + std::to_string(r.stored()) + ",\"reports\":" + std::to_string(r.reports) +
         ",\"dropped\":" + std::to_string(r.dropped) + ",\"skipped\":" + std::to_string(r.skipped) +
         ",\"ahead\":" + std::to_string(r.ahead) + "}";
  }
  return s + "}";
}

class Driver {
 public:
  int run() {
    return ev3prog::run_driver_lines(nullptr, seq_, [this](const std::string& line) { return handle(line); });
  }

 private:
  std::string error(const std::string& msg) const { return ev3prog::driver_error(kProgram, seq_, msg); }

  /// The agent an input names ("agent": an id 2..49999).
  bool agent_of(const Json& in, std::uint16_t& id, std::string& err) const {
    const long long a = in["agent"].kind == Json::Kind::number ? in["agent"].n : -1;
    if (a < 0 || a > 0xFFFF || !ev3proto::is_assigned_id(static_cast<std::uint16_t>(a))) {
      err = "\"agent\" must be an assigned id (2..49999)";
      return false;
    }
    id = static_cast<std::uint16_t>(a);
    return true;
  }

  /// A field that must be one of two names (@p a is its default when absent).
  static bool one_of(const Json& in, const char* key, const char* a, const char* b, std::string& out, std::string& err) {
    out = in[key].kind == Json::Kind::null ? a : in[key].str("?");
    if (out == a || out == b) return true;
    err = std::string("\"") + key + "\" must be \"" + a + "\" or \"" + b + "\"";
    return false;
  }
  /// A field that must be a number 0..4294967295 (@p dflt when absent).
  static bool u32(const Json& in, const char* key, long long dflt, long long& out, std::string& err) {
    out = in[key].kind == Json::Kind::null ? dflt : in[key].kind == Json::Kind::number ? in[key].n : -1;
    if (out >= 0 && out <= 0xFFFFFFFFLL) return true;
    err = std::string("\"") + key + "\" must be a number 0..4294967295";
    return false;
  }

  Buffer& buffer(std::uint16_t id) {
    auto it = w_.agents.find(id);
    if (it == w_.agents.end()) {
      it = w_.agents.emplace(id, Buffer{}).first;
      it->second.set_limit(w_.cap);
    }
    return it->second;
  }

  /// Spec Send: a round of retries (everything the current master has not acknowledged, from its
  /// start), as many datagrams as the window gives. To the interim master (@p to_im), each is taken
  /// by its record at once (PCTake) and `im_ack` answers what it acknowledges.
  std::string send(std::uint16_t id, bool to_im, std::string& extra) {
    Buffer& b = buffer(id);
    b.retry();
    std::string s = ",\"sent\":[";
    bool marker = false, first = true;
    std::uint32_t seq = 0;
    std::string_view datagram;
    while (b.next(marker, seq, datagram)) {
      const std::uint32_t from = marker ? b.lo() : seq, last = seq;
      const std::uint32_t lo = b.lo();
      b.sent(seq);
      if (!first) s += ',';
      first = false;
      s += "{\"seq\":" + std::to_string(from) + ",\"last\":" + std::to_string(last) + ",\"first\":" +
           std::to_string(lo) + ",\"kind\":\"" + (marker ? "dropped" : "report") + "\"}";
      if (to_im) {
        std::uint32_t skipped = 0;
        ev3proto::PCTake(w_.im[id], from, marker ? last : 0, lo, skipped);
      }
    }
    s += "]";
    if (to_im) s += ",\"im_ack\":" + std::to_string(w_.im[id].stored());
    extra = s;
    return {};
  }

  std::string handle(const std::string& line) {
    Json in;
    std::string err;
    if (!ev3prog::parse_json(line, in, err)) return error("not JSON: " + err);
    if (in.kind != Json::Kind::object) return error("an input is a JSON object");
    const std::string type = in["type"].str();
    std::string extra;
    std::uint16_t id = 0;
    if (type == "config") {
      long long cap = 0;
      if (!u32(in, "cap", 64, cap, err) || cap < 1 || cap > 64)
        return error("\"cap\" must be 1..64 (reports an agent holds at once)");
      w_ = World{};
      w_.cap = static_cast<std::size_t>(cap);
      w_.file = std::string(ev3proto::kRecordHeader) + "\n";
    } else if (type == "make") {
      if (!agent_of(in, id, err)) return error(err);
      Buffer& b = buffer(id);
      const std::string report = "report " + std::to_string(b.made() + 1);
      extra = ",\"seq\":" + std::to_string(b.Make(report));
    } else if (type == "send") {
      std::string to;
      if (!agent_of(in, id, err) || !one_of(in, "to", "pc", "im", to, err)) return error(err);
      send(id, to == "im", extra);
    } else if (type == "take_ack") {
      long long n = 0;
      if (!agent_of(in, id, err) || !u32(in, "n", -1, n, err)) return error(err);
      const bool ok = buffer(id).TakeAck(static_cast<std::uint32_t>(n), in["pc"].boolean(), in["current"].boolean());
      extra = std::string(",\"taken\":") + (ok ? "true" : "false");
    } else if (type == "new_master") {
      if (!agent_of(in, id, err)) return error(err);
      buffer(id).new_master();
    } else if (type == "take") {
      std::string m;
      long long seq = 0, last = 0, first = 0;
      if (!agent_of(in, id, err) || !one_of(in, "master", "pc", "im", m, err) || !u32(in, "seq", -1, seq, err) ||
          !u32(in, "last", 0, last, err) || !u32(in, "first", -1, first, err))
        return error(err);
      if (seq == 0 || first == 0) return error("\"seq\" and \"first\" must be report numbers (1 or more)");
      auto& rs = m == "pc" ? w_.pc : w_.im;
      const bool known = rs.count(id) != 0;
      ReportRecord& r = rs[id];
      const ReportRecord before = r;
      std::uint32_t skipped = 0;
      const ReportTaken t = ev3proto::PCTake(r, static_cast<std::uint32_t>(seq), static_cast<std::uint32_t>(last),
                                             static_cast<std::uint32_t>(first), skipped);
      if (t == ReportTaken::invalid) {
        if (!known) rs.erase(id);  // an invalid offer opens no record
      } else if (m == "pc") {
        note(id, before, r);
      }
      extra = std::string(",\"taken\":\"") + taken_name(t) + "\",\"skipped\":" + std::to_string(skipped);
    } else if (type == "ack") {
      std::string m;
      if (!agent_of(in, id, err) || !one_of(in, "master", "pc", "im", m, err)) return error(err);
      const auto& rs = m == "pc" ? w_.pc : w_.im;
      const auto it = rs.find(id);
      extra = ",\"ack\":" + std::to_string(it == rs.end() ? 0u : it->second.stored());
    } else if (type == "crash") {
      // The PC stops and starts again: what it holds of each agent is its record file, read back.
      std::map<std::uint16_t, ReportRecord> back;
      std::size_t start = 0, n = 0;
      for (std::size_t nl; (nl = w_.file.find('\n', start)) != std::string::npos; start = nl + 1) {
        ++n;
        if (!ev3proto::apply_record_line(std::string_view(w_.file).substr(start, nl - start), back, err))
          return error("the record file's line " + std::to_string(n) + " is refused: " + err);
      }
      w_.pc = std::move(back);
    } else if (type == "save") {
      snaps_.insert_or_assign(in["slot"].num(), w_);
    } else if (type == "restore") {
      auto it = snaps_.find(in["slot"].num());
      if (it == snaps_.end()) return error("no snapshot in that slot");
      w_ = it->second;
    } else if (type != "check") {
      return error("unknown input type '" + type + "' (" + kInputs + ")");
    }
    return output(extra);
  }

  /// The record file's lines for what PCTake added to @p id's record (it was @p before), as
  /// ev3-master --record appends them.
  void note(std::uint16_t id, const ReportRecord& before, const ReportRecord& r) {
    ev3proto::record_events(id, ev3proto::taken_entries(before, r), ev3proto::MsgType::SENSOR_VALUE,
                            "report " + std::to_string(r.next - 1),
                            [this](ev3proto::OperatorEvent&& e) { w_.file += ev3proto::record_line(e); });
  }

  std::string output(const std::string& extra) const {
    std::string s = ev3prog::output_start(seq_, true) + extra + ",\"agents\":{";
    bool first = true;
    for (const auto& [id, b] : w_.agents) {
      if (!first) s += ',';
      first = false;
      s += "\"" + std::to_string(id) + "\":{\"made\":" + std::to_string(b.made()) + ",\"lo\":" + std::to_string(b.lo()) +
           ",\"mk\":" + std::to_string(b.mk()) + ",\"held\":" + std::to_string(b.held()) + ",\"dropped\":" +
           std::to_string(b.dropped()) + ",\"current_ack\":" + std::to_string(b.current_ack()) + "}";
    }
    s += "},\"pc\":" + records_json(w_.pc) + ",\"im\":" + records_json(w_.im) + ",\"record\":";
    ev3proto::json_string(s, w_.file);
    return s + "}";
  }

  World w_;
  std::map<long long, World> snaps_;
  unsigned long long seq_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: %s\n\n"
          "The library's reliable reports (an agent's report buffer, a master's record of each\n"
          "agent, the PC's record file) one spec step at a time: one NDJSON input per stdin line\n"
          "(%s), one NDJSON output line per input on stdout.\n"
          "docs/driver.md \"Reports driver\" has the protocol.\n",
          kProgram, kInputs);
      return 0;
    }
    std::fprintf(stderr, "%s: takes no arguments but --help (got '%s')\n", kProgram, a.c_str());
    return 2;
  }
  static Driver d;
  return d.run();
}
