// ev3-master: the fleet's master. The I/O around the master core (libev3proto master.hpp): a UDP
// socket, one event loop (ppoll) over the socket, the console's stdin and the control socket's
// connections (--control) that sleeps until the next datagram, command line or deadline (core
// resends and drops, copy sends, script waits, status JSON, table refresh, a control command's time
// to wait for its robots). On a terminal: a live table refreshed in place and a prompt; otherwise answers
// and events are log lines on stdout. docs/programs.md describes it.
#include <fcntl.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <ev3proto/durable.hpp>
#include <ev3proto/master.hpp>
#include <ev3proto/record.hpp>
#include <ev3proto/trace.hpp>

#include "ev3prog/console.hpp"
#include "ev3prog/control.hpp"
#include "ev3prog/program.hpp"
#include "ev3prog/script.hpp"
#include "ev3prog/trace_file.hpp"
#include "driver.hpp"
#include "ev3io/line_server.hpp"
#include "ev3io/log.hpp"
#include "ev3io/loop.hpp"
#include "ev3io/udp.hpp"
#include "master_options.hpp"
#include "record_db.hpp"

namespace {

using namespace ev3io::levels;
using ev3proto::Millis;

using MasterCore = ev3proto::Master<ev3proto::NdjsonTrace>;

constexpr Millis kStatusEveryMs = 500;
constexpr Millis kRedrawEveryMs = 500;
constexpr int kTableRows = 14;

/// The drop counter of a datagram the core ignored (or took without effect): "decode:<reason>"
/// for one that does not decode, else the core's spelling ("misaddressed", "unknown_sender", ...).
std::string drop_key(const ev3proto::MasterReceipt& r) {
  return r.why == ev3proto::MasterIgnored::malformed ? ev3prog::decode_drop_key(r.reason)
                                                     : std::string(ev3proto::to_string(r.why));
}

class Program {
 public:
  explicit Program(const ev3master::MasterOptions& o) : opt_(o), sh_("ev3-master", o.common.faults) {}

  int run() {
    tty_ = isatty(0) && isatty(1);
    if (const int rc = sh_.open("master", opt_.common)) return rc;
    if (tty_ && opt_.common.log_file.empty() && opt_.common.log_level > kError)
      sh_.log.set_level(kError);  // the terminal shows the table; only errors go to stderr there
    if (sh_.trace_file.is_open()) trace_.set_output(sh_.trace_file.output());
    if (!sh_.load_script("--script", opt_.script)) return 2;
    start_ = ev3io::monotonic_ms();
    sh_.script.start(start_);
    ev3proto::MasterConfig cfg;
    cfg.timers = opt_.timers;
    cfg.max_resends = opt_.max_resends;
    cfg.election = opt_.election;
    cfg.drop_copies = true;  // every datagram arrives 3 times (the transport's copies)
    cfg.durable_first = true;  // no datagram but through ready(), after its state is written
    // Without a state file to continue from, msgids start from the wall clock, above what an earlier
    // run sent (agents ignore a command below one they remember: ev3proto/msgids.hpp).
    cfg.next_msgid = ev3proto::master_msgid_seed(ev3io::wall_ms());
    std::string restored, recorded;
    if (!load_state(cfg, restored)) return 2;
    if (!load_record(cfg, recorded)) return 2;
    if (!opt_.db.empty()) {
      const std::string err = db_.open(opt_.db);
      if (!err.empty()) {
        std::fprintf(stderr, "ev3-master: %s\n", err.c_str());
        return 2;
      }
    }
    if (!opt_.control.empty()) {
      const std::string err = control_.open(opt_.control, opt_.control_group);
      if (!err.empty()) {
        std::fprintf(stderr, "ev3-master: %s\n", err.c_str());
        return 2;
      }
      control_.on_close = [this](ev3io::LineServer::Client c) { answers_.forget(c); };
      control_.busy = [this](ev3io::LineServer::Client c) { return answers_.waiting(c) != 0; };
    }
    master_.emplace(cfg, start_, sh_.trace_file.is_open() ? &trace_ : nullptr);
    ready(start_);  // the state file written at once (nothing is queued yet)
    if (sh_.state_failed) return 1;
    listening_ = sh_.net.local().str();
    sh_.log.log(kInfo, "listening on %s", listening_.c_str());
    sh_.log.flush();
    if (tty_) setup_screen();
    else say("listening on " + listening_);
    if (!restored.empty()) say(restored);
    if (!recorded.empty()) say(recorded);
    if (db_.is_open()) say("record " + opt_.db + ": " + db_.opened());
    election_changes();
    loop();
    shutdown();
    return sh_.state_failed ? 1 : 0;
  }

 private:
  void loop() {
    while (sh_.running() && !quit_) {
      // At most Shell::kBatch datagrams, then what is owed (PONGs, resends, copies, status).
      const bool more = sh_.receive([this](const std::string& d, const ev3io::Endpoint& from, Millis now) {
        on_datagram(d, from, now);
      });
      const Millis now = ev3io::monotonic_ms();
      master_->advance(now);
      pump(now);
      run_script(now);
      sh_.net.flush(now);
      if (!opt_.status_json.empty() && now >= next_status_) {
        write_status(now);
        next_status_ = now + kStatusEveryMs;
      }
      if (tty_ && now >= next_redraw_) {
        redraw(now);
        next_redraw_ = now + kRedrawEveryMs;
      }
      if (db_.is_open()) commit_db(now);
      if (quit_) break;
      for (const auto& a : answers_.expire(now)) control_.send(a.client, a.line);
      Millis deadline = std::min({master_->next_deadline(), sh_.script.deadline(), answers_.deadline()});
      if (!opt_.status_json.empty()) deadline = std::min(deadline, next_status_);
      if (tty_) deadline = std::min(deadline, next_redraw_);
      pollfd fds[ev3prog::Shell::kMaxExtra];
      std::size_t n = 0;
      if (stdin_open_) fds[n++] = pollfd{0, POLLIN, 0};
      const std::size_t first_control = n;
      n += control_.fds(fds + n);
      if (sh_.wait(now, deadline, more, fds, n) <= 0) continue;
      if (stdin_open_ && first_control == 1 && (fds[0].revents & (POLLIN | POLLHUP | POLLERR)) != 0)
        read_stdin(ev3io::monotonic_ms());
      control_.serve(fds + first_control, n - first_control,
                     [this](ev3io::LineServer::Client c, const std::string& line) {
                       control_line(c, line, ev3io::monotonic_ms());
                     },
                     [this] { return ev3prog::control_error(opt_.json, "line too long (at most 65536 bytes)"); });
    }
  }

  /// A line from a control connection: the console language, one answer per line (docs/programs.md
  /// "The control socket"). A command to robots is answered when they have answered it.
  void control_line(ev3io::LineServer::Client client, const std::string& text, Millis now) {
    if (quit_) return;  // after a quit, nothing more is sent
    const ev3prog::ControlLine l = ev3prog::parse_control_line(text, opt_.json);
    ev3prog::ConsoleCommand c;
    const std::string err = ev3prog::console_command(l.command, c);
    if (!err.empty()) {
      control_.send(client, ev3prog::control_error(l.json, err));
      return;
    }
    using K = ev3prog::ConsoleCommand::Kind;
    switch (c.kind) {
      case K::none: return;  // an empty line or a comment: no answer
      case K::help: control_.send(client, ev3prog::control_ok(l.json, ev3prog::console_help())); return;
      case K::list:
        control_.send(client, ev3prog::control_list(
                                  l.json, view_.table(master_->registry(), sh_.drops, now, master_->report_records()),
                                  view_.status_json(master_->registry(), sh_.drops, listening_, master_->next_id(), now,
                                                    start_, master_->report_records())));
        return;
      case K::quit:
        say("quit (control socket)");
        control_.send(client, ev3prog::control_ok(l.json, "quit"));
        quit_ = true;
        return;
      case K::rule: {
        const std::string said = view_.set_rule(c);
        say(said);
        const bool failed = said.rfind("error: ", 0) == 0;
        control_.send(client, failed ? ev3prog::control_error(l.json, said.substr(7)) : ev3prog::control_ok(l.json, said));
        return;
      }
      case K::wait: control_.send(client, ev3prog::control_error(l.json, "wait is for scripts (--script)")); return;
      case K::send:
        say("> " + l.command + " (control socket)");
        send_command(client, l.json, c.agent, c.command, now);
        return;
    }
  }

  /// The operator's command to agent @p agent (0: all), from the console, a script or a rule (client
  /// 0) or a control connection: tagged, so that its robots' answers go back to whoever asked and
  /// to its row of the record (--db).
  void send_command(ev3io::LineServer::Client client, bool json, std::uint16_t agent, ev3proto::Command cmd,
                    Millis now) {
    cmd.tag = ++last_tag_;
    std::vector<std::uint16_t> to = master_->command(agent, cmd, now);  // `all`: every robot it has
    std::size_t queued = 0;  // the most commands queued ahead of this one at one robot
    for (std::uint16_t a : to) queued = std::max(queued, master_->registry().at(a).queue.size() - 1);
    if (agent != 0 && to.empty()) to.push_back(agent);  // unknown: the core answers unknown_agent
    if (client != 0) {
      // The commands queued ahead each take their resends first; then the agent timeout.
      const Millis resends = (opt_.max_resends + 1) * opt_.timers[ev3proto::Timer::resend];
      const Millis limit = (queued + 1) * resends + opt_.timers[ev3proto::Timer::drop];
      for (const auto& a : answers_.sent(client, json, cmd.tag, cmd.type, agent, to, now, limit))
        control_.send(a.client, a.line);
    }
    if (db_.is_open()) {
      std::string args = cmd.name;
      for (const std::string& x : cmd.args) args += (args.empty() ? "" : " ") + x;
      const auto t = static_cast<std::int64_t>(ev3io::wall_ms());
      for (std::uint16_t a : to)
        if (master_->registry().count(a) != 0)
          db_commands_[{cmd.tag, a}] = db_.command_sent(a, std::string(to_string(cmd.type)), args, t);
    }
    pump(now);
  }

  /// A datagram for the core; what it ignored (or took without effect) is counted by the reason
  /// the core gives.
  void on_datagram(const std::string& d, const ev3io::Endpoint& from, Millis now) {
    const ev3proto::MasterReceipt r = master_->handle_datagram(d, sh_.net.peer_of(from), now);
    if (r.why != ev3proto::MasterIgnored::none) {
      sh_.drop(drop_key(r), d, &from);
    }
    if (r.taken()) {
      sh_.log.log(kDebug, "recv %s from %s: %s", d.c_str(), from.str().c_str(),
               std::string(to_string(r.action)).c_str());
      if (r.action == ev3proto::Action::MasterHandover) handovers_++;
      pump(now);
    }
  }

  /// The core's ready(): the state file written (ids, msgids, epoch, membership), then what the
  /// calls queued sent. A failed write stops the master: nothing more is sent (a msgid or an id
  /// handed out must not be handed out again after a restart, an epoch must not be stood in twice).
  void ready(Millis now) {
    if (sh_.state_failed) return;
    sh_.state_failed = !master_->ready([this](const ev3proto::MasterDurable& d) { return save_state(d); },
                   [this](const std::vector<ev3proto::OperatorEvent>& r) { return append_record(r); },
                   [this, now](const ev3proto::MasterTransmit& t) {
                     if (t.dest == ev3proto::Dest::broadcast) {  // ELECT, LEADER
                       sh_.log.log(kDebug, "send %s to everyone", t.bytes.c_str());
                       for (const auto& b : opt_.common.broadcast) sh_.net.send(b, t.bytes, now);
                       return;
                     }
                     const ev3io::Endpoint* ep = sh_.net.endpoint_of(t.peer);
                     if (ep == nullptr) {
                       sh_.count("no_route");
                       sh_.log.log(kVerbose, "drop (no_route): no address for peer %u", static_cast<unsigned>(t.peer));
                       return;
                     }
                     sh_.log.log(kDebug, "send %s to %s", t.bytes.c_str(), ep->str().c_str());
                     sh_.net.send(*ep, t.bytes, now);
                   });
  }

  /// The core's events (console, --db, control answers, rules), then its ready(). A report the
  /// core recorded is committed to --db before ready() sends the REPORT_ACK that covers it; the
  /// other rows wait for the end of the loop turn.
  void pump(Millis now) {
    election_changes();
    ev3proto::OperatorEvent e;
    std::vector<ev3prog::FleetView::RuleCommand> ruled;
    bool recorded = false;
    while (master_->poll_event(e)) {
      say(view_.on_event(e, ev3prog::agent_address(master_->registry(), e.agent, sh_.net), now));
      if (db_.is_open()) record_event(e);
      recorded = recorded || e.recorded();
      for (const auto& a : answers_.on_event(e)) control_.send(a.client, a.line);
      if (auto r = view_.follow_rules(e, master_->registry())) ruled.push_back(std::move(*r));
      dirty_ = true;
    }
    if (recorded && db_.is_open()) commit_db(now);
    ready(now);
    for (const ev3prog::FleetView::RuleCommand& r : ruled) {
      say(r.say);
      send_command(0, false, r.agent, r.command, now);
    }
    if (dirty_ && tty_) {
      redraw(now);
      dirty_ = false;
    }
  }

  void read_stdin(Millis now) {
    char buf[4096];
    const ssize_t n = read(0, buf, sizeof buf);
    if (n <= 0) {
      stdin_open_ = false;  // EOF: keep running (quit or a signal stops the master)
      if (tty_) quit_ = true;  // Ctrl-D on the terminal
      return;
    }
    inbuf_.append(buf, static_cast<std::size_t>(n));
    for (std::size_t nl; (nl = inbuf_.find('\n')) != std::string::npos;) {
      const std::string line = inbuf_.substr(0, nl);
      inbuf_.erase(0, nl + 1);
      handle_line(line, false, now);
      if (quit_) return;
    }
    if (tty_) prompt();
  }

  void run_script(Millis now) {
    std::string line;
    while (!quit_ && sh_.script.next(now, line)) handle_line(line, true, now);
  }

  void handle_line(const std::string& line, bool script, Millis now) {
    ev3prog::ConsoleCommand c;
    const std::string err = ev3prog::console_command(line, c);
    if (!err.empty()) {
      say("error: " + err);
      return;
    }
    using K = ev3prog::ConsoleCommand::Kind;
    switch (c.kind) {
      case K::none: return;
      case K::help: say(ev3prog::console_help()); return;
      case K::list:
        for (const std::string& l : view_.table(master_->registry(), sh_.drops, now, master_->report_records())) say(l);
        return;
      case K::quit: say("quit"); quit_ = true; return;
      case K::rule: say(view_.set_rule(c)); return;
      case K::wait:
        if (!script) say("error: wait is for scripts (--script)");
        return;
      case K::send:
        say("> " + line);
        send_command(0, false, c.agent, c.command, now);
        return;
    }
  }

  /// One line for the operator.
  void say(const std::string& text) {
    sh_.log.log(kDebug, "console: %s", text.c_str());
    if (tty_) {
      std::string s = "\r\033[K" + text + "\n";
      std::fwrite(s.data(), 1, s.size(), stdout);
      prompt();
      return;
    }
    const Millis t = ev3io::monotonic_ms() - start_;
    std::printf("[%6llu.%03llu] %s\n", static_cast<unsigned long long>(t / 1000),
                static_cast<unsigned long long>(t % 1000), text.c_str());
    std::fflush(stdout);
  }

  void prompt() {
    std::fputs("\r\033[Kev3> ", stdout);
    std::fflush(stdout);
  }

  void setup_screen() {
    winsize ws{};
    rows_ = ioctl(1, TIOCGWINSZ, &ws) == 0 && ws.ws_row > kTableRows + 4 ? ws.ws_row : 24;
    std::printf("\033[2J\033[%d;%dr\033[%d;1H", kTableRows + 1, rows_, rows_);
    say("ev3-master listening on " + listening_ + "; " + ev3prog::console_help());
    redraw(ev3io::monotonic_ms());
  }

  void redraw(Millis now) {
    std::vector<std::string> t = view_.table(master_->registry(), sh_.drops, now, master_->report_records());
    std::string s = "\0337";
    char head[96];
    std::snprintf(head, sizeof head, "ev3-master %s  up %.0fs  agents %zu", listening_.c_str(),
                  static_cast<double>(now - start_) / 1000.0, master_->registry().size());
    t.insert(t.begin(), head);
    for (int i = 0; i < kTableRows; ++i) {
      s += "\033[" + std::to_string(i + 1) + ";1H";
      if (static_cast<std::size_t>(i) < t.size()) s += (i == 0 ? "\033[7m" + t[0] + "\033[0m" : t[static_cast<std::size_t>(i)]);
      else if (i == kTableRows - 1) s += std::string(72, '-');
      s += "\033[K";
    }
    s += "\0338";
    std::fwrite(s.data(), 1, s.size(), stdout);
    std::fflush(stdout);
  }

  void write_status(Millis now) {
    const std::string doc = view_.status_json(master_->registry(), sh_.drops, listening_, master_->next_id(), now, start_,
                                              master_->report_records());
    const std::string tmp = opt_.status_json + ".tmp";
    std::FILE* f = std::fopen(tmp.c_str(), "w");
    if (f == nullptr) {
      if (!status_warned_) sh_.log.log(kError, "cannot write %s: %s", tmp.c_str(), std::strerror(errno));
      status_warned_ = true;
      return;
    }
    std::fwrite(doc.data(), 1, doc.size(), f);
    std::fputc('\n', f);
    std::fclose(f);
    std::rename(tmp.c_str(), opt_.status_json.c_str());
  }

  void shutdown() {
    const Millis now = ev3io::monotonic_ms();
    sh_.log_stop(quit_ ? "quit" : nullptr);
    if (!opt_.status_json.empty()) write_status(now);
    if (tty_) {
      std::printf("\033[r\033[%d;1H\n", rows_);
      std::fflush(stdout);
    } else {
      say("stopped");
    }
    if (record_fd_ >= 0) ::close(record_fd_);
    if (db_.is_open()) {
      last_seen(now);
      commit_db(now);
      db_.close();
    }
    control_.close();
    sh_.close();
  }

  /// --state-file: restores next id, msgid (the end of the reserved block), epoch and members; the
  /// master then starts as a candidate (Election Restart(PC), docs/core.md).
  bool load_state(ev3proto::MasterConfig& cfg, std::string& note) {
    if (opt_.state_file.empty()) return true;
    std::optional<std::string> text;
    if (!sh_.read_state("--state-file", opt_.state_file, text)) return false;
    if (!text) return true;  // a first start
    // The library's rule (ev3proto/durable.hpp), the one ev3-agent's file is read by (the PC keeps no
    // floor). The membership is that of the epoch members_epoch: what LEADER carried, what votes
    // count against; a list without its epoch is refused: the floor of the agents' votes rests on it.
    ev3proto::MasterDurable d;
    ev3proto::DurableError why;
    if (!ev3proto::parse_master_durable(*text, d, why)) return sh_.damaged("--state-file", opt_.state_file, why.view());
    cfg.next_id = d.next_id;
    cfg.next_msgid = d.next_msgid;
    cfg.epoch = d.epoch;
    cfg.members.assign(d.members, d.members + d.member_count);
    cfg.members_epoch = d.members_epoch;
    cfg.candidate = cfg.election;
    const std::string members(ev3proto::IdListText().ids(d.members, d.member_count).view());
    note = "restarted from " + opt_.state_file + ": next id " + std::to_string(d.next_id) + ", msgid " +
           std::to_string(d.next_msgid) + ", epoch " + std::to_string(d.epoch) + ", members " +
           (members.empty() ? "none" : members) + (cfg.election ? "; standing to take the fleet back" : "");
    return true;
  }

  /// --record: reads the record of reports back (record.hpp's rule) so that each agent's record
  /// continues where it ends (the core never hands out a recorded agent's id again), and opens the
  /// file for appending. A line that is not an entry, or does not follow the agent's previous one,
  /// is refused naming its number; a last line cut by a crash (no newline) is cut off the file.
  bool load_record(ev3proto::MasterConfig& cfg, std::string& note) {
    if (opt_.record.empty()) return true;
    cfg.keep_record = true;
    std::string text;
    if (std::FILE* f = std::fopen(opt_.record.c_str(), "rb")) {
      char buf[65536];
      for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) text.append(buf, n);
      std::fclose(f);
    } else if (errno != ENOENT) {
      std::fprintf(stderr, "ev3-master: --record %s: cannot read it: %s\n", opt_.record.c_str(), std::strerror(errno));
      return false;
    }
    std::size_t lines = 0, entries = 0, pos = 0;
    for (; pos < text.size();) {
      const std::size_t nl = text.find('\n', pos);
      if (nl == std::string::npos) break;  // cut by a crash: cut off below
      ++lines;
      std::string why;
      const std::string_view line(text.data() + pos, nl - pos);
      if (!ev3proto::apply_record_line(line, cfg.records, why)) {
        std::fprintf(stderr, "ev3-master: --record %s: line %zu: %s\n", opt_.record.c_str(), lines, why.c_str());
        return false;
      }
      if (!line.empty() && line[0] != '#') ++entries;
      pos = nl + 1;
    }
    record_fd_ = ::open(opt_.record.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (record_fd_ < 0 || (pos < text.size() && ::ftruncate(record_fd_, static_cast<off_t>(pos)) != 0)) {
      std::fprintf(stderr, "ev3-master: --record %s: cannot write it: %s\n", opt_.record.c_str(), std::strerror(errno));
      return false;
    }
    if (text.empty()) {
      const std::string head = std::string(ev3proto::kRecordHeader) + "\n";
      if (::write(record_fd_, head.data(), head.size()) != static_cast<ssize_t>(head.size())) {
        std::fprintf(stderr, "ev3-master: --record %s: cannot write it: %s\n", opt_.record.c_str(), std::strerror(errno));
        return false;
      }
    }
    if (entries != 0)
      note = "record " + opt_.record + ": " + std::to_string(entries) + " entries of " +
             std::to_string(cfg.records.size()) + " agents" +
             (pos < text.size() ? "; a last line cut by a crash was cut off" : "");
    return true;
  }

  /// Appends the record's new entries (--record) and flushes them to the disk; false when they
  /// are not on it (then the master sends nothing more, no acknowledgement among it, and exits
  /// with status 1).
  bool append_record(const std::vector<ev3proto::OperatorEvent>& entries) {
    if (record_fd_ < 0) return true;
    std::string text;
    for (const ev3proto::OperatorEvent& e : entries) text += ev3proto::record_line(e);
    for (std::size_t done = 0; done < text.size();) {
      const ssize_t n = ::write(record_fd_, text.data() + done, text.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        sh_.log.log(kError, "cannot append to the record %s: %s", opt_.record.c_str(), std::strerror(errno));
        return false;
      }
      done += static_cast<std::size_t>(n);
    }
    if (::fdatasync(record_fd_) != 0) {
      sh_.log.log(kError, "cannot flush the record %s: %s", opt_.record.c_str(), std::strerror(errno));
      return false;
    }
    return true;
  }

  /// Writes the state the core's ready() hands over (--state-file); false when it is not on disk
  /// (then the master sends nothing more and exits with status 1, as ev3-agent does).
  bool save_state(const ev3proto::MasterDurable& d) {
    return sh_.save_state("the master's state", opt_.state_file, ev3proto::durable_text(d).view());
  }

  /// Election observers (role, epoch, handover): one console line per change.
  /// --db: the rows of an operator event (docs/record.md).
  void record_event(const ev3proto::OperatorEvent& e) {
    using K = ev3proto::OperatorEvent::Kind;
    const auto t = static_cast<std::int64_t>(ev3io::wall_ms());
    const std::string type(to_string(e.command));
    switch (e.kind) {
      case K::registered: {
        const auto it = master_->registry().find(e.agent);
        const bool known = it != master_->registry().end() && !it->second.model.empty();
        db_.robot_seen(e.agent, it == master_->registry().end() ? 0 : it->second.ann,
                       ev3prog::agent_address(master_->registry(), e.agent, sh_.net),
                       known ? it->second.model : std::string(), known ? ev3proto::json_list(it->second.devices) : std::string(),
                       t);
        db_.state(e.agent, "SYNCED", t);
        return;
      }
      case K::state: db_.state(e.agent, e.text, t); return;
      case K::dropped: db_.state(e.agent, "LOST", t); return;
      case K::acked:
      case K::refused:
      case K::timed_out: {
        const auto it = db_commands_.find({e.tag, e.agent});
        if (it == db_commands_.end()) return;  // a command the core made itself (reconcile's)
        db_.command_answered(it->second, std::string(to_string(e.kind)), e.kind == K::refused ? e.text : "", t);
        db_commands_.erase(it);
        return;
      }
      case K::unknown_agent: return;  // no row was written for a command to no agent
      case K::report: db_.report(e.agent, e.seq, type, e.text, t); return;
      case K::reports_dropped: db_.reports_missing(e.agent, e.seq, e.last, "dropped", t); return;
      case K::reports_skipped: db_.reports_missing(e.agent, e.seq, e.last, "skipped", t); return;
    }
  }
  /// --db: when each registered robot was last heard (every 5 s, and at exit).
  void last_seen(Millis now) {
    const auto wall = static_cast<std::int64_t>(ev3io::wall_ms());
    for (const auto& kv : master_->registry())
      db_.robots_heard(kv.first, wall - static_cast<std::int64_t>(now > kv.second.heard ? now - kv.second.heard : 0));
    next_seen_ = now + 5000;
  }
  /// --db: the loop turn's rows in one transaction. A failed write is said (once per cause) and the
  /// master goes on: the record file (--record) is what the acknowledgements wait for.
  void commit_db(Millis now) {
    if (now >= next_seen_) last_seen(now);
    const std::string err = db_.commit();
    if (!err.empty() && err != db_failed_) {
      sh_.log.log(kError, "--db %s: %s", opt_.db.c_str(), err.c_str());
      say("error: --db " + opt_.db + ": " + err);
    }
    db_failed_ = err;
  }

  void election_changes() {
    if (!opt_.election) return;
    const ev3proto::MasterRole r = master_->role();
    if (r != seen_role_ || master_->epoch() != seen_epoch_) {
      seen_role_ = r;
      seen_epoch_ = master_->epoch();
      view_.set_election(std::string(to_string(r)), seen_epoch_);
      std::string members;
      for (std::uint16_t m : master_->members()) members += " " + std::to_string(m);
      say("election: " + std::string(to_string(r)) + " of epoch " + std::to_string(seen_epoch_) + " (members" +
          (members.empty() ? " none" : members) + " of epoch " + std::to_string(master_->members_epoch()) + ")");
      if (db_.is_open())
        db_.epoch(seen_epoch_, std::string(to_string(r)), members.empty() ? "" : members.substr(1),
                  static_cast<std::int64_t>(ev3io::wall_ms()));
    }
    if (handovers_ != seen_handovers_) {  // (handed_over() is an elected agent's side: never the PC's)
      seen_handovers_ = handovers_;
      say("election: the elected agent handed the fleet over (HANDOVER)");
    }
  }

  ev3master::MasterOptions opt_;
  ev3prog::Shell sh_;  // log, signals, socket, trace file, script, drop counters, state-file writes
  ev3proto::NdjsonTrace trace_{"master"};
  std::optional<MasterCore> master_;
  ev3master::RecordDb db_;           // --db
  std::map<std::pair<std::uint32_t, std::uint16_t>, std::int64_t> db_commands_;  // (tag, agent) -> row
  std::uint32_t last_tag_ = 0;       // the operator's commands, numbered (Command::tag)
  Millis next_seen_ = 0;             // --db: the robots' last_seen_ms written next
  std::string db_failed_;            // --db: the last write error said
  ev3prog::ControlAnswers answers_;  // the commands waiting for their robots' answers
  ev3io::LineServer control_;        // --control (after answers_: its on_close uses them)
  ev3prog::FleetView view_;
  std::string inbuf_;
  std::string listening_;
  Millis start_ = 0, next_status_ = 0, next_redraw_ = 0;
  bool tty_ = false, stdin_open_ = true, quit_ = false, dirty_ = false, status_warned_ = false;
  int rows_ = 24;
  // --state-file, election
  std::uint32_t handovers_ = 0, seen_handovers_ = 0;  // HANDOVERs taken, and said
  ev3proto::MasterRole seen_role_ = ev3proto::MasterRole::master;
  std::uint32_t seen_epoch_ = 0;
  int record_fd_ = -1;  // --record, open for appending
};

}  // namespace

int main(int argc, char** argv) {
  return ev3prog::program_main<Program>(argc, argv, "ev3-master", ev3master::run_driver, ev3master::parse_master_options);
}
