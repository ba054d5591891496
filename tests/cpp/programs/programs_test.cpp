// Unit tests of the programs' non-I/O logic: ev3-agent / ev3-master options (both command-line
// forms), the fault injection schedule, the console parser and view; and of the shared program
// library's console scripts, trace file and text files. (The behaviours `wait` and `drive` are the
// robot runtime's: tests/cpp/robot.)
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "ev3io/state_file.hpp"
#include "ev3prog/console.hpp"
#include "ev3prog/control.hpp"
#include "ev3prog/program.hpp"
#include "ev3prog/script.hpp"
#include "ev3prog/trace_file.hpp"
#include "ev3io/cli.hpp"
#include "ev3io/fault.hpp"
#include "ev3io/udp.hpp"
#include "agent_options.hpp"
#include "master_options.hpp"

namespace {

using ev3proto::Millis;
using ev3proto::Timer;

ev3agent::ParseOutcome agent_args(std::vector<const char*> v, ev3agent::AgentOptions& o, std::string& msg) {
  v.insert(v.begin(), "ev3-agent");
  return ev3agent::parse_agent_options(static_cast<int>(v.size()), v.data(), o, msg);
}

TEST(AgentOptions, Defaults) {
  ev3agent::AgentOptions o;
  std::string m;
  ASSERT_EQ(agent_args({}, o, m), ev3agent::ParseOutcome::run) << m;
  EXPECT_EQ(o.common.port, 12345);
  EXPECT_EQ(o.model, "A");
  EXPECT_EQ(o.sysfs_root, "/sys");
  EXPECT_EQ(o.ports.of(ev3proto::robot::Role::left), ev3proto::robot::Dev::outB);
  EXPECT_EQ(o.ports.of(ev3proto::robot::Role::ultrasonic), ev3proto::robot::Dev::in4);
  EXPECT_EQ(o.tick_ms, 20u);
  ASSERT_EQ(agent_args({"--ports", "left=outA,right=outD,touch=in2", "--tick-ms", "10"}, o, m),
            ev3agent::ParseOutcome::run) << m;
  EXPECT_EQ(o.ports.of(ev3proto::robot::Role::left), ev3proto::robot::Dev::outA);
  EXPECT_EQ(o.ports.of(ev3proto::robot::Role::right), ev3proto::robot::Dev::outD);
  EXPECT_EQ(o.ports.of(ev3proto::robot::Role::touch), ev3proto::robot::Dev::in2);
  EXPECT_EQ(o.tick_ms, 10u);
  EXPECT_EQ(o.timers[Timer::sync], 10000u);
  ASSERT_EQ(o.common.broadcast.size(), 1u);
  EXPECT_EQ(o.common.broadcast[0].str(), "255.255.255.255:12345");
  EXPECT_EQ(o.common.log_level, 2);
}

TEST(AgentOptions, ThesisForm) {
  ev3agent::AgentOptions o;
  std::string m;
  ASSERT_EQ(agent_args({"agent", "port=12233", "model=B", "loglevel=4"}, o, m), ev3agent::ParseOutcome::run) << m;
  EXPECT_EQ(o.common.port, 12233);
  EXPECT_EQ(o.model, "B");
  EXPECT_EQ(o.common.log_level, 4);
}

TEST(AgentOptions, FlagsBothSpellingsAndRepeatedBroadcast) {
  ev3agent::AgentOptions o;
  std::string m;
  ASSERT_EQ(agent_args({"--port=0", "--broadcast", "127.0.0.1:5000", "--broadcast=127.0.0.1:5001",
                        "--heartbeat-ms", "200", "--master-timeout-ms", "1000", "--fault-loss", "12.5",
                        "--fault-seed", "7"},
                       o, m),
            ev3agent::ParseOutcome::run)
      << m;
  EXPECT_EQ(o.common.port, 0);
  ASSERT_EQ(o.common.broadcast.size(), 2u);
  EXPECT_EQ(o.common.broadcast[1].port, 5001);
  EXPECT_EQ(o.timers[Timer::heartbeat], 200u);
  EXPECT_EQ(o.timers[Timer::loss], 1000u);
  EXPECT_EQ(o.timers[Timer::paused], 2000u);  // 2 x master timeout unless given
  EXPECT_DOUBLE_EQ(o.common.faults.loss, 12.5);
  EXPECT_EQ(o.common.faults.seed, 7u);
}

TEST(AgentOptions, StartPoseAndPoseReports) {
  ev3agent::AgentOptions o;
  std::string m;
  ASSERT_EQ(agent_args({"--pose", "25,-30.5,-90", "--pose-ms", "0"}, o, m), ev3agent::ParseOutcome::run) << m;
  EXPECT_DOUBLE_EQ(o.pose.x_mm, 250.0);
  EXPECT_DOUBLE_EQ(o.pose.y_mm, -305.0);
  EXPECT_DOUBLE_EQ(o.pose.heading_deg, 270.0);
  EXPECT_EQ(o.pose_ms, 0u);
  ev3agent::AgentOptions d;
  ASSERT_EQ(agent_args({}, d, m), ev3agent::ParseOutcome::run) << m;
  EXPECT_EQ(d.pose_ms, 1000u);
  EXPECT_DOUBLE_EQ(d.pose.x_mm, 0.0);
}

TEST(AgentOptions, ErrorsNameTheFlag) {
  const std::vector<std::pair<std::vector<const char*>, std::string>> bad = {
      {{"--port", "70000"}, "--port"},
      {{"--port", "x"}, "--port"},
      {{"--log-level", "5"}, "--log-level"},
      {{"--broadcast", "nohost"}, "--broadcast"},
      {{"--bind", "1.2.3"}, "--bind"},
      {{"--frobnicate"}, "frobnicate"},
      {{"colour=red"}, "colour"},
      {{"--heartbeat-ms"}, "--heartbeat-ms"},
      {{"--fault-loss", "101"}, "--fault-loss"},
      {{"--master-timeout-ms", "500", "--paused-timeout-ms", "400"}, "--paused-timeout-ms"},
      {{"--model", "a:b"}, "--model"},
      {{"--ports", "left=in1"}, "--ports: left needs an output port"},
      {{"--ports", "touch=in3"}, "--ports: in3 given to both touch and colour"},
      {{"--ports", "wheel=outA"}, "--ports: unknown role 'wheel'"},
      {{"--tick-ms", "4"}, "--tick-ms"},
      {{"--tick-ms", "101"}, "--tick-ms"},
      {{"--pose", "1,2"}, "--pose: '1,2' (expected X,Y,HEADING"},
      {{"--pose", "1,2,x"}, "--pose"},
      {{"--pose", "1,2,3,4"}, "--pose"},
      {{"--pose", "1e9,0,0"}, "--pose"},
      {{"--pose-ms", "60001"}, "--pose-ms"},
      {{"stray"}, "stray"},
  };
  for (const auto& b : bad) {
    ev3agent::AgentOptions o;
    std::string m;
    EXPECT_EQ(agent_args(b.first, o, m), ev3agent::ParseOutcome::error) << b.second;
    EXPECT_NE(m.find(b.second), std::string::npos) << m;
  }
  ev3agent::AgentOptions o;
  std::string m;
  EXPECT_EQ(agent_args({"--help"}, o, m), ev3agent::ParseOutcome::help);
  EXPECT_NE(m.find("--sysfs-root"), std::string::npos);
}

TEST(MasterOptions, ParsesItsFlags) {
  ev3master::MasterOptions o;
  std::string m;
  std::vector<const char*> v = {"ev3-master", "--agent-timeout-ms", "1500", "--status-json", "/tmp/s.json",
                                "--script", "/tmp/x", "--max-resends", "2"};
  ASSERT_EQ(ev3master::parse_master_options(static_cast<int>(v.size()), v.data(), o, m),
            ev3master::ParseOutcome::run)
      << m;
  EXPECT_EQ(o.timers[Timer::drop], 1500u);
  EXPECT_EQ(o.status_json, "/tmp/s.json");
  EXPECT_EQ(o.max_resends, 2u);
  std::vector<const char*> bad = {"ev3-master", "--agent-timeout-ms", "0"};
  EXPECT_EQ(ev3master::parse_master_options(3, bad.data(), o, m), ev3master::ParseOutcome::error);
  EXPECT_NE(m.find("--agent-timeout-ms"), std::string::npos);
}

TEST(Fault, NoFaultsIsIdentity) {
  ev3io::FaultInjector f;
  std::vector<Millis> out;
  for (Millis t = 0; t < 100; ++t) f.schedule(t, out);
  ASSERT_EQ(out.size(), 100u);
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_EQ(out[i], static_cast<Millis>(i));
}

TEST(Fault, DeterministicGivenTheSeedAndRoughlyTheRates) {
  ev3io::FaultConfig c;
  c.loss = 20;
  c.dup = 10;
  c.reorder = 5;
  c.delay_ms = 7;
  c.seed = 42;
  ev3io::FaultInjector a(c), b(c);
  std::vector<Millis> oa, ob;
  for (Millis t = 0; t < 10000; ++t) {
    a.schedule(t, oa);
    b.schedule(t, ob);
  }
  EXPECT_EQ(oa, ob);
  EXPECT_NEAR(static_cast<double>(a.stats().lost), 2000, 200);
  EXPECT_NEAR(static_cast<double>(a.stats().duplicated), 800, 150);
  EXPECT_GT(a.stats().reordered, 0u);
  for (Millis t : oa) EXPECT_GE(t, 7u);
  c.seed = 43;
  ev3io::FaultInjector d(c);
  std::vector<Millis> od;
  for (Millis t = 0; t < 10000; ++t) d.schedule(t, od);
  EXPECT_NE(oa, od);
}

TEST(Endpoint, Parse) {
  ev3io::Endpoint e;
  EXPECT_TRUE(ev3io::parse_endpoint("127.0.0.1:12345", e));
  EXPECT_EQ(e.str(), "127.0.0.1:12345");
  EXPECT_TRUE(ev3io::parse_endpoint("localhost:1", e));
  for (const char* s : {"127.0.0.1", "127.0.0.1:0", "127.0.0.1:65536", "x:1", "127.0.0.1:01", ":5"})
    EXPECT_FALSE(ev3io::parse_endpoint(s, e)) << s;
}

TEST(Console, Commands) {
  ev3prog::ConsoleCommand c;
  EXPECT_EQ(ev3prog::parse_console_line("behaviour 2 wait seconds=3", c), "");
  EXPECT_EQ(c.kind, ev3prog::ConsoleCommand::Kind::send);
  EXPECT_EQ(c.agent, 2);
  EXPECT_EQ(c.command.type, ev3proto::MsgType::BEHAVIOUR);
  EXPECT_EQ(c.command.name, "wait");
  ASSERT_EQ(c.command.args.size(), 1u);
  EXPECT_EQ(c.command.args[0], "seconds=3");
  EXPECT_EQ(ev3prog::parse_console_line("  pause   all ", c), "");
  EXPECT_EQ(c.agent, 0);
  EXPECT_EQ(c.command.type, ev3proto::MsgType::PAUSE);
  EXPECT_EQ(ev3prog::parse_console_line("wait 1.5", c), "");
  EXPECT_DOUBLE_EQ(c.seconds, 1.5);
  EXPECT_EQ(ev3prog::parse_console_line("# comment", c), "");
  EXPECT_EQ(c.kind, ev3prog::ConsoleCommand::Kind::none);
  EXPECT_NE(ev3prog::parse_console_line("fly 2", c).find("unknown command 'fly'"), std::string::npos);
  EXPECT_NE(ev3prog::parse_console_line("start two", c).find("bad agent id 'two'"), std::string::npos);
  EXPECT_NE(ev3prog::parse_console_line("start", c).find("bad argument"), std::string::npos);
  EXPECT_NE(ev3prog::parse_console_line("behaviour 2 wait 3", c).find("'3'"), std::string::npos);
  EXPECT_NE(ev3prog::parse_console_line("list x", c), "");
}

TEST(Console, ViewAndStatusJson) {
  ev3prog::FleetView v;
  ev3proto::OperatorEvent e{ev3proto::OperatorEvent::Kind::registered, 2, ev3proto::MsgType::MASTER, "50001"};
  EXPECT_NE(v.on_event(e, "127.0.0.1:4000", 10).find("agent 2 registered"), std::string::npos);
  e = {ev3proto::OperatorEvent::Kind::refused, 2, ev3proto::MsgType::START, "no behaviour"};
  EXPECT_EQ(v.on_event(e, "", 11), "agent 2: START refused (NOT): no behaviour");
  e = {ev3proto::OperatorEvent::Kind::report, 2, ev3proto::MsgType::EVENT, "BATTERY:7.4"};
  v.on_event(e, "", 12);
  EXPECT_EQ(v.info()[2].battery, "7.4");
  e = {ev3proto::OperatorEvent::Kind::unknown_agent, 9, ev3proto::MsgType::START, ""};
  EXPECT_EQ(v.on_event(e, "", 13), "error: unknown agent id 9");
  std::map<std::uint16_t, ev3proto::RegistryEntry> reg;
  reg[2].id = 2;
  reg[2].synced = true;
  const std::string j = v.status_json(reg, {{"misaddressed", 3}}, "127.0.0.1:1", 3, 100, 0);
  EXPECT_NE(j.find("\"battery\":\"7.4\""), std::string::npos) << j;
  EXPECT_NE(j.find("\"misaddressed\":3"), std::string::npos) << j;
  e = {ev3proto::OperatorEvent::Kind::dropped, 2, ev3proto::MsgType::PING, ""};
  v.on_event(e, "", 50);
  EXPECT_EQ(v.lost().size(), 1u);
  const auto t = v.table({}, {}, 100);
  EXPECT_NE(t.back().find("lost: 2"), std::string::npos);
}

/// A file under the test's temporary directory (removed by the test).
std::string temp_path(const char* name) {
  const char* dir = std::getenv("TMPDIR");
  return std::string(dir != nullptr ? dir : "/tmp") + "/ev3prog_" + std::to_string(getpid()) + "_" + name;
}

void write_file(const std::string& path, const char* text) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr);
  std::fputs(text, f);
  std::fclose(f);
}

TEST(Console, CustomBehaviourFromAFileIsCheckedAndSentCompact) {
  const std::string path = temp_path("spin.bhv");
  write_file(path,
             "# spin: turn on the spot, forever\n"
             "behaviour spin\n"
             "param angle = 90\n"
             "state turning = turn $angle speed=200 -> turning   # again\n"
             "on OBSTACLE_DETECTED, PROXIMITY_ALERT -> end\n");
  ev3prog::ConsoleCommand c;
  ASSERT_EQ(ev3prog::console_command("behaviour 3 custom @" + path + " angle=45", c), "");
  EXPECT_EQ(c.kind, ev3prog::ConsoleCommand::Kind::send);
  EXPECT_EQ(c.command.name, "custom");
  ASSERT_EQ(c.command.args.size(), 2u);
  EXPECT_EQ(c.command.args[1], "angle=45");
  const std::string& sent = c.command.args[0];
  EXPECT_EQ(sent.find('#'), std::string::npos) << sent;   // no comments on the wire
  EXPECT_EQ(sent.find('\n'), std::string::npos) << sent;  // one line
  EXPECT_NE(sent.find("behaviour spin"), std::string::npos) << sent;
  EXPECT_NE(sent.find("param angle=90;"), std::string::npos) << sent;  // as written: the argument travels after it

  // A definition that does not parse is refused at the console, with the file and the place.
  write_file(path, "behaviour spin\nstate turning = trun 90 -> turning\n");
  std::string err = ev3prog::console_command("behaviour 3 custom @" + path, c);
  EXPECT_EQ(err.rfind("refused before sending: " + path + ": line 2 col 17: unknown action 'trun'", 0), 0u) << err;
  // One that parses but does not check: a moving state without a reaction to a bump.
  write_file(path, "behaviour spin\nstate turning = turn 90 speed=200 -> turning\n");
  err = ev3prog::console_command("behaviour 3 custom @" + path, c);
  EXPECT_NE(err.find(path + ": line 2"), std::string::npos) << err;
  EXPECT_NE(err.find("OBSTACLE_DETECTED"), std::string::npos) << err;
  std::remove(path.c_str());
  EXPECT_EQ(ev3prog::console_command("behaviour 3 custom @" + path, c), "cannot read " + path + ": no such file");
  EXPECT_NE(ev3prog::parse_console_line("behaviour 3 custom spin.bhv", c).find("custom takes @FILE.bhv"),
            std::string::npos);
}

TEST(Console, BuiltinBehavioursAreCheckedBeforeSending) {
  ev3prog::ConsoleCommand c;
  EXPECT_EQ(ev3prog::console_command("behaviour all explore speed=300 angle=90", c), "");
  EXPECT_EQ(c.command.args.size(), 2u);  // a built-in travels by name
  std::string err = ev3prog::console_command("behaviour 2 explore speed=5000", c);
  EXPECT_EQ(err.rfind("refused before sending: behaviour explore: ", 0), 0u) << err;
  EXPECT_NE(err.find("speed"), std::string::npos) << err;
  err = ev3prog::console_command("behaviour 2 explore sped=300", c);
  EXPECT_NE(err.find("unknown param 'sped'"), std::string::npos) << err;
  err = ev3prog::console_command("behaviour 2 fly", c);
  EXPECT_NE(err.find("unknown behaviour 'fly' (built-ins: "), std::string::npos) << err;
}

TEST(Console, ExploreExploitRule) {
  ev3prog::ConsoleCommand c;
  EXPECT_NE(ev3prog::parse_console_line("rule explore-exploit purple", c).find("unknown colour 'purple'"),
            std::string::npos);
  EXPECT_NE(ev3prog::parse_console_line("rule fly red", c).find("rule takes explore-exploit"), std::string::npos);
  ASSERT_EQ(ev3prog::parse_console_line("rule explore-exploit red speed=200", c), "");
  EXPECT_EQ(c.kind, ev3prog::ConsoleCommand::Kind::rule);
  ev3prog::FleetView v;
  std::map<std::uint16_t, ev3proto::RegistryEntry> reg;
  reg[2].id = 2;
  reg[2].behaviour = "explore";
  reg[3].id = 3;
  reg[3].behaviour = "drive";
  using K = ev3proto::OperatorEvent::Kind;
  using ev3proto::MsgType;
  const ev3proto::OperatorEvent red{K::report, 2, MsgType::SENSOR_VALUE, "in3:COL-COLOR:5"};
  EXPECT_FALSE(v.follow_rules(red, reg)) << "the rule is off until switched on";
  EXPECT_NE(v.set_rule(c).find("on"), std::string::npos);
  // Not the colour, not the colour mode, not exploring: nothing.
  EXPECT_FALSE(v.follow_rules({K::report, 2, MsgType::SENSOR_VALUE, "in3:COL-COLOR:3"}, reg));
  EXPECT_FALSE(v.follow_rules({K::report, 2, MsgType::SENSOR_VALUE, "in3:COL-REFLECT:5"}, reg));
  EXPECT_FALSE(v.follow_rules({K::report, 3, MsgType::SENSOR_VALUE, "in3:COL-COLOR:5"}, reg));
  const auto r = v.follow_rules(red, reg);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->agent, 2);
  EXPECT_EQ(r->command.name, "exploit");
  EXPECT_EQ(r->command.args, (std::vector<std::string>{"colour=red", "speed=200"}));
  EXPECT_FALSE(v.follow_rules(red, reg)) << "sent once, until the robot explores again";
  reg[2].behaviour = "exploit";  // acknowledged
  EXPECT_FALSE(v.follow_rules(red, reg));
  reg[2].behaviour = "explore";  // the operator sent it exploring again
  EXPECT_TRUE(v.follow_rules(red, reg));
  ASSERT_EQ(ev3prog::parse_console_line("rule explore-exploit off", c), "");
  v.set_rule(c);
  reg[3].behaviour = "explore";
  EXPECT_FALSE(v.follow_rules({K::report, 3, MsgType::SENSOR_VALUE, "in3:COL-COLOR:5"}, reg));
}

TEST(ExploreExploit, TheLibrarySwitchesARobotOncePerExploreRun) {
  ev3proto::ExploreExploit rule;
  ASSERT_EQ(rule.switch_on("red"), "");
  ev3proto::RegistryEntry e;
  e.id = 2;
  e.behaviour = "explore";
  using K = ev3proto::OperatorEvent::Kind;
  const ev3proto::OperatorEvent red{K::report, 2, ev3proto::MsgType::SENSOR_VALUE, "in3:COL-COLOR:5"};
  EXPECT_TRUE(rule.on_report(red, e));
  EXPECT_FALSE(rule.on_report(red, e)) << "switched in this explore run: not again";
  e.behaviour = "exploit";
  EXPECT_FALSE(rule.on_report({K::state, 2, ev3proto::MsgType::START, "WORKING"}, e));
  e.behaviour = "explore";  // told to explore again: a candidate again
  EXPECT_TRUE(rule.on_report(red, e));
  rule.switch_off();
  ASSERT_EQ(rule.switch_on("red"), "");
  EXPECT_TRUE(rule.on_report(red, e)) << "switching the rule off forgets who was switched";
}

TEST(Console, ListShowsStepAndLastReport) {
  ev3prog::FleetView v;
  using K = ev3proto::OperatorEvent::Kind;
  v.on_event({K::report, 2, ev3proto::MsgType::ACTION_OK, "forward"}, "", 1000);
  v.on_event({K::report, 2, ev3proto::MsgType::SENSOR_VALUE, "in4:US-DIST-CM:42"}, "", 2000);
  std::map<std::uint16_t, ev3proto::RegistryEntry> reg;
  reg[2].id = 2;
  reg[2].synced = true;
  reg[2].behaviour = "explore";
  const auto t = v.table(reg, {}, 3500);
  ASSERT_GE(t.size(), 2u);
  EXPECT_NE(t[0].find("STEP"), std::string::npos) << t[0];
  EXPECT_NE(t[1].find("explore"), std::string::npos) << t[1];
  EXPECT_NE(t[1].find("forward"), std::string::npos) << t[1];
  EXPECT_NE(t[1].find("SENSOR_VALUE in4 US-DIST-CM 42 (1.5s ago)"), std::string::npos) << t[1];
  const std::string j = v.status_json(reg, {}, "x", 3, 3500, 0);
  EXPECT_NE(j.find("\"step\":\"forward\""), std::string::npos) << j;
}

TEST(Script, LinesDueWithWaitsBetween) {
  ev3prog::Script s;
  s.set_lines({"start all", "wait 1.5", "# note", "pause 2", "wait 0.5", "list"});
  std::string line;
  EXPECT_FALSE(s.next(0, line));  // not started
  EXPECT_EQ(s.deadline(), ~Millis{0});
  s.start(1000);
  EXPECT_EQ(s.deadline(), 1000u);
  ASSERT_TRUE(s.next(1000, line));
  EXPECT_EQ(line, "start all");
  EXPECT_FALSE(s.next(1000, line));  // the wait is taken: the next line at 2500
  EXPECT_EQ(s.deadline(), 2500u);
  EXPECT_FALSE(s.next(2499, line));
  ASSERT_TRUE(s.next(2500, line));
  EXPECT_EQ(line, "# note");  // comments are the program's to skip (parse_console_line: none)
  ASSERT_TRUE(s.next(2500, line));
  EXPECT_EQ(line, "pause 2");
  EXPECT_FALSE(s.next(2500, line));  // the program asks again at once: the wait starts now
  EXPECT_FALSE(s.next(2999, line));
  ASSERT_TRUE(s.next(3000, line));
  EXPECT_EQ(line, "list");
  EXPECT_FALSE(s.next(99999, line));
  EXPECT_EQ(s.deadline(), ~Millis{0});
  s.start(5);  // again from the top (an agent elected a second time)
  ASSERT_TRUE(s.next(5, line));
  EXPECT_EQ(line, "start all");
}

TEST(Script, LoadsAFileAndNamesAMissingOne) {
  const std::string path = temp_path("script.txt");
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr);
  std::fputs("start all\nwait 1\nstop all", f);  // no newline after the last line
  std::fclose(f);
  ev3prog::Script s;
  EXPECT_EQ(s.load(path), "");
  EXPECT_FALSE(s.empty());
  s.start(0);
  std::string line;
  ASSERT_TRUE(s.next(0, line));
  EXPECT_EQ(line, "start all");
  EXPECT_FALSE(s.next(0, line));
  ASSERT_TRUE(s.next(1000, line));
  EXPECT_EQ(line, "stop all");
  std::remove(path.c_str());
  EXPECT_EQ(s.load(path), "cannot open '" + path + "': no such file");
}

TEST(Files, ReadLinesKeepsEveryLine) {
  const std::string path = temp_path("lines.txt");
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr);
  std::fputs("a=1\n\n# c\nlast", f);
  std::fclose(f);
  std::vector<std::string> lines;
  std::string err;
  ASSERT_TRUE(ev3io::read_lines(path, lines, err)) << err;
  EXPECT_EQ(lines, (std::vector<std::string>{"a=1", "", "# c", "last"}));
  std::string text;
  ASSERT_TRUE(ev3io::read_state_file(path, text, err)) << err;
  EXPECT_EQ(text, "a=1\n\n# c\nlast\n");
  std::remove(path.c_str());
  lines.clear();
  EXPECT_FALSE(ev3io::read_lines(path, lines, err));
  EXPECT_EQ(err, "");  // a missing file: no error text (a first start)
}

TEST(TraceFile, LinesFlushedEvery200ms) {
  const std::string path = temp_path("trace.ndjson");
  ev3prog::TraceFile t;
  EXPECT_FALSE(t.is_open());
  EXPECT_EQ(t.tick(0), ~Millis{0});
  EXPECT_NE(t.open("/nonexistent-dir/t.ndjson").find("cannot open '/nonexistent-dir/t.ndjson'"), std::string::npos);
  ASSERT_EQ(t.open(path), "");
  t.output()("{\"a\":1}");
  EXPECT_EQ(t.tick(1000), 1200u);  // flushed now, next at +200
  EXPECT_EQ(t.tick(1100), 1200u);
  std::vector<std::string> lines;
  std::string err;
  ASSERT_TRUE(ev3io::read_lines(path, lines, err));
  EXPECT_EQ(lines, (std::vector<std::string>{"{\"a\":1}"}));
  t.write("{\"b\":2}");
  t.close();
  EXPECT_FALSE(t.is_open());
  lines.clear();
  ASSERT_TRUE(ev3io::read_lines(path, lines, err));
  EXPECT_EQ(lines.size(), 2u);
  std::remove(path.c_str());
}

// A state write flushes the trace first: a program killed right after announcing an epoch leaves
// the record of the change in its trace (the merged-run check needs it to know who was elected).
TEST(Shell, StateWriteFlushesTheTraceFirst) {
  const std::string trace = temp_path("shell_trace.ndjson"), state = temp_path("shell.state");
  ev3prog::Shell sh("ev3-test", ev3io::FaultConfig{});
  ASSERT_EQ(sh.trace_file.open(trace), "");
  sh.trace_file.write("{\"action\":\"BecomeMaster\"}");
  std::vector<std::string> lines;
  std::string err;
  ASSERT_TRUE(ev3io::read_lines(trace, lines, err));
  EXPECT_TRUE(lines.empty());  // still in the buffer
  ASSERT_TRUE(sh.save_state("the test's state", state, "epoch 4\n"));
  ASSERT_TRUE(ev3io::read_lines(trace, lines, err));
  EXPECT_EQ(lines, (std::vector<std::string>{"{\"action\":\"BecomeMaster\"}"}));
  sh.trace_file.write("{\"action\":\"Vote\"}");
  EXPECT_TRUE(sh.save_state("the test's state", "", "epoch 5\n"));  // no state file: the trace still flushed
  lines.clear();
  ASSERT_TRUE(ev3io::read_lines(trace, lines, err));
  EXPECT_EQ(lines.size(), 2u);
  sh.trace_file.close();
  std::remove(trace.c_str());
  std::remove(state.c_str());
}

}  // namespace


// The control socket's answers (ev3prog/control.hpp): by tag, never another command's answer.
TEST(Control, AnswersGoToTheirCommandByTag) {
  using ev3proto::MsgType;
  using ev3proto::OperatorEvent;
  ev3prog::ControlAnswers w;
  auto ev = [](OperatorEvent::Kind k, std::uint16_t agent, MsgType t, std::uint32_t tag, std::string text = {}) {
    OperatorEvent e{k, agent, t, std::move(text)};
    e.tag = tag;
    return e;
  };
  EXPECT_TRUE(w.sent(1, false, 7, MsgType::PAUSE, 3, {3}, 0, 1000).empty());
  EXPECT_TRUE(w.sent(2, true, 8, MsgType::PAUSE, 0, {3, 4}, 0, 1000).empty());
  // The core's own PAUSE (tag 0) and another command's answer are nobody's here.
  EXPECT_TRUE(w.on_event(ev(OperatorEvent::Kind::acked, 3, MsgType::PAUSE, 0)).empty());
  EXPECT_TRUE(w.on_event(ev(OperatorEvent::Kind::acked, 3, MsgType::PAUSE, 99)).empty());
  auto a = w.on_event(ev(OperatorEvent::Kind::acked, 3, MsgType::PAUSE, 8));
  EXPECT_TRUE(a.empty());  // robot 4 still owes its answer
  a = w.on_event(ev(OperatorEvent::Kind::refused, 3, MsgType::PAUSE, 7, "busy"));
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].client, 1u);
  EXPECT_EQ(a[0].line, "error: 3 PAUSE refused (busy)");
  a = w.on_event(ev(OperatorEvent::Kind::dropped, 4, MsgType::START, 0));  // robot 4 lost
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].line,
            "{\"ok\":false,\"command\":\"PAUSE\",\"agent\":\"all\",\"answers\":[{\"agent\":3,\"answer\":\"acked\"},"
            "{\"agent\":4,\"answer\":\"lost\"}]}");
  EXPECT_EQ(w.waiting(1) + w.waiting(2), 0u);
  // No answer in time; a client gone waits no more.
  EXPECT_TRUE(w.sent(1, false, 9, MsgType::STOP, 5, {5}, 100, 50).empty());
  EXPECT_TRUE(w.sent(2, false, 10, MsgType::STOP, 5, {5}, 100, 50).empty());
  EXPECT_EQ(w.deadline(), 150u);
  w.forget(2);
  a = w.expire(150);
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].line, "error: 5 STOP no_answer");
  EXPECT_EQ(w.deadline(), ev3prog::ControlAnswers::kNever);
  a = w.sent(1, false, 11, MsgType::START, 0, {}, 0, 50);  // all, to no robot: answered at once
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].line, "ok: all START: no agents");
  EXPECT_EQ(ev3prog::parse_control_line("  --json  list\r", false).command, "list");
  EXPECT_TRUE(ev3prog::parse_control_line("--json list", false).json);
  EXPECT_FALSE(ev3prog::parse_control_line("--jsonx", false).json);
}
