// The automaton (ev3proto/behaviour/automaton.hpp) without devices: transcripts (testdata/automaton_*.txt)
// and the built-ins `wait` and `drive` written in the language giving the plans the hard-coded ones give
// (robot/behaviours.hpp). EV3_REWRITE=1 rewrites the transcripts' expectations.
//
// Commands (one per input line; the automaton lives across the cases of a file):
//   load NAME [KEY=VALUE]...   a built-in (behaviours/*.bhv), its params set, checked on model A
//   define [KEY=VALUE]...      the case's other lines are the definition (then as load)
//   at MS                      the time is MS, then a control tick (conditions, reports)
//   read SENSOR VALUE|none     the last reading of a sensor (base units, or a colour word)
//   start | pause | resume | continue | stop | restart   the lifecycle (continue: CONTINUE)
//   finish                     the running plan finished
//   fail                       the running plan failed
//   event NAME                 an event (it interrupts the plan when the state reacts with a state)
//   phase                      where the automaton is
// Output: one line an output: `start STATE: STEP; STEP ... [xN] {interrupted by EVENT,...}`, `pause`,
// `resume`, `halt MODE`, `ACTION_OK ID (STATE)`, `ACTION_INTERR ID EVENT (STATE)`, `ACTION_ERR ID (STATE)`,
// `SENSOR_VALUE SENSOR`, `done (MODE)`; errors of load / define as `error: ...`.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "check_file.hpp"
#include "ev3proto/behaviour/automaton.hpp"
#include "ev3proto/behaviour/builtins.hpp"
#include "ev3proto/behaviour/checker.hpp"
#include "ev3proto/behaviour/parser.hpp"
#include "ev3proto/robot/behaviours.hpp"
#include "transcript.hpp"

namespace {

using namespace ev3proto::behaviour;
namespace action = ev3proto::robot::action;
using ev3proto::robot::EventKind;
using ev3proto::robot::StopAction;

std::string describe(const action::Step& s) {
  std::ostringstream o;
  o << to_string(s.kind);
  switch (s.kind) {
    case action::Kind::drive_distance: o << " " << s.mm << " mm at " << s.speed << " " << to_string(s.stop); break;
    case action::Kind::turn: o << " " << s.degrees << " deg at " << s.speed << " " << to_string(s.stop); break;
    case action::Kind::run_forever: o << " " << s.speed << "/" << s.speed_right << " " << to_string(s.stop); break;
    case action::Kind::stop: o << " " << to_string(s.stop); break;
    case action::Kind::pause: o << " " << s.ms << " ms"; if (s.sensors) o << " read ports " << int{s.sensors}; break;
    case action::Kind::wait: o << " " << s.ms << " ms"; break;
  }
  return o.str();
}

std::string describe(const action::Plan& p) {
  std::ostringstream o;
  for (std::uint8_t i = 0; i < p.count; ++i) o << (i ? "; " : " ") << describe(p.steps[i]);
  if (p.times != 1) o << " [x" << p.times << "]";
  if (p.count > 0 && p.steps[0].interrupts != 0) {
    o << " {interrupted by";
    const char* sep = " ";
    for (std::size_t e = 0; e < ev3proto::robot::kEventKindCount; ++e)
      if (ev3proto::robot::contains(p.steps[0].interrupts, static_cast<EventKind>(e))) {
        o << sep << to_string(static_cast<EventKind>(e));
        sep = ", ";
      }
    o << "}";
  }
  return o.str();
}

// Sensor ports of model A's default --ports: touch in1, colour in3, ultrasonic in4 (no gyro).
constexpr std::uint8_t kPorts[kSensorCount] = {1u << 3, 1u << 0, 1u << 2, 0};

class Driver {
 public:
  std::string run(const std::vector<std::string>& input) {
    out_.str("");
    for (std::size_t i = 0; i < input.size(); ++i) {
      std::istringstream in(input[i]);
      std::string verb;
      in >> verb;
      std::vector<std::string> args;
      for (std::string a; in >> a;) args.push_back(a);
      if (verb == "define") {
        std::string text;
        for (std::size_t k = i + 1; k < input.size(); ++k) text += input[k] + "\n";
        load(text, args);
        break;
      }
      command(verb, args);
      drain();
    }
    return out_.str();
  }

 private:
  void load(const std::string& text, const std::vector<std::string>& sets) {
    static Definition def;
    Diagnostic diag;
    std::vector<std::string_view> views(sets.begin(), sets.end());
    Findings f;
    if (!parse(text, def, diag) || !apply_args(def, views.data(), views.size(), diag)) {
      out_ << "error: " << bhvtest::diag_line(diag) << "\n";
    } else if (!check(def, kModelA, f)) {
      out_ << "error: " << bhvtest::diag_line(f.items[0]) << "\n";
    } else {
      a_.load(def, kPorts);
      out_ << "loaded " << def.name.view() << "\n";
    }
  }

  static bool sensor_named(const std::string& n, Sensor& s) {
    for (std::size_t k = 0; k < kSensorCount; ++k)
      if (to_string(static_cast<Sensor>(k)) == n) {
        s = static_cast<Sensor>(k);
        return true;
      }
    return false;
  }
  static bool event_named(const std::string& n, EventKind& e) {
    for (std::size_t k = 0; k < ev3proto::robot::kEventKindCount; ++k)
      if (to_string(static_cast<EventKind>(k)) == n) {
        e = static_cast<EventKind>(k);
        return true;
      }
    return false;
  }

  void command(const std::string& verb, const std::vector<std::string>& args) {
    if (verb == "load") {
      const Builtin* b = args.empty() ? nullptr : find_builtin(args[0]);
      if (b == nullptr) {
        out_ << "error: no built-in " << (args.empty() ? "" : args[0]) << "\n";
        return;
      }
      load(std::string(b->text), std::vector<std::string>(args.begin() + 1, args.end()));
    } else if (verb == "at" && args.size() == 1) {
      now_ = std::stoul(args[0]);
      a_.tick(now_, readings_);
    } else if (verb == "read" && args.size() == 2) {
      Sensor s;
      if (!sensor_named(args[0], s)) {
        out_ << "error: unknown sensor " << args[0] << "\n";
        return;
      }
      Reading& r = readings_[static_cast<std::size_t>(s)];
      r.valid = args[1] != "none";
      Number n;
      if (word_colour(args[1], n)) r.value = n.value;
      else if (r.valid) r.value = std::stoi(args[1]);
    } else if (verb == "start") {
      a_.start(now_);
    } else if (verb == "restart") {
      a_.restart(now_);
    } else if (verb == "pause") {
      a_.pause();
    } else if (verb == "resume") {
      a_.resume(now_);
    } else if (verb == "continue") {
      a_.go_on(now_);
    } else if (verb == "stop") {
      a_.stop();
    } else if (verb == "finish") {
      a_.finished();
    } else if (verb == "fail") {
      a_.failed();
    } else if (verb == "event" && args.size() == 1) {
      EventKind e;
      if (!event_named(args[0], e)) {
        out_ << "error: unknown event " << args[0] << "\n";
        return;
      }
      if (!a_.event(e)) out_ << "(" << args[0] << " changes nothing)\n";
    } else if (verb == "phase") {
      out_ << "phase " << to_string(a_.phase()) << ", state "
           << a_.definition().states[a_.state()].name.view() << ", next id " << a_.next_id() << "\n";
    } else {
      out_ << "error: unknown command " << verb << "\n";
    }
  }

  static bool word_colour(const std::string& w, Number& n) {
    for (std::int32_t c = 0; c <= static_cast<std::int32_t>(Colour::brown); ++c)
      if (to_string(static_cast<Colour>(c)) == w) {
        n.value = c;
        return true;
      }
    return false;
  }

  void drain() {
    const Definition& d = a_.definition();
    for (Output o; a_.poll(o);) {
      const std::string_view state = o.state < d.state_count ? d.states[o.state].name.view() : "?";
      out_ << to_string(o.kind);
      switch (o.kind) {
        case Output::Kind::start: out_ << " " << state << ":" << describe(a_.plan()); break;
        case Output::Kind::ok: out_ << " " << o.id << " (" << state << ")"; break;
        case Output::Kind::interrupted: out_ << " " << o.id << " " << to_string(o.event) << " (" << state << ")"; break;
        case Output::Kind::error: out_ << " " << o.id << " (" << state << ")"; break;
        case Output::Kind::report: out_ << " " << to_string(o.sensor); break;
        case Output::Kind::halt: out_ << " " << to_string(o.stop); break;
        case Output::Kind::done: out_ << " (" << to_string(o.stop) << ")"; break;
        case Output::Kind::pause:
        case Output::Kind::resume: break;
      }
      out_ << "\n";
    }
  }

  Automaton a_;
  Reading readings_[kSensorCount];
  ev3proto::robot::Millis now_ = 0;
  std::ostringstream out_;
};

class AutomatonTranscript : public ::testing::TestWithParam<std::string> {};

TEST_P(AutomatonTranscript, Matches) {
  Driver d;
  bhvtest::check_file(GetParam(), [&](const datadriven::Case& c) { return d.run(c.input); });
}

INSTANTIATE_TEST_SUITE_P(Testdata, AutomatonTranscript, ::testing::ValuesIn(bhvtest::transcripts("automaton_")), bhvtest::name_of);

// The built-ins wait and drive in the language start the plan the hard-coded ones build.
action::Plan language_plan(const char* name, std::vector<std::string_view> args) {
  static Definition def;
  Diagnostic diag;
  EXPECT_TRUE(parse(find_builtin(name)->text, def, diag));
  EXPECT_TRUE(apply_args(def, args.data(), args.size(), diag)) << bhvtest::diag_line(diag);
  static Automaton a;
  a.load(def, kPorts);
  a.start(0);
  Output o;
  EXPECT_TRUE(a.poll(o));
  EXPECT_EQ(o.kind, Output::Kind::start);
  return a.plan();
}

void expect_same(const action::Plan& a, const action::Plan& b) {
  ASSERT_EQ(a.count, b.count);
  EXPECT_EQ(a.times, b.times);
  for (std::uint8_t i = 0; i < a.count; ++i) {
    EXPECT_EQ(describe(a.steps[i]), describe(b.steps[i]));
    EXPECT_EQ(a.steps[i].interrupts, b.steps[i].interrupts) << describe(a.steps[i]);
    EXPECT_EQ(a.steps[i].ms, b.steps[i].ms);
  }
}

TEST(AutomatonBuiltins, WaitAndDriveStartTheHardCodedPlans) {
  ev3proto::robot::ReasonText why;
  action::Plan hard;
  const std::string_view wait_args[] = {"seconds=1.5"};
  ASSERT_TRUE(ev3proto::robot::build_behaviour("wait", wait_args, 1, hard, why));
  expect_same(language_plan("wait", {"seconds=1.5"}), hard);
  for (const char* stop : {"stop=brake", "stop=coast", "stop=hold"}) {
    const std::string_view drive_args[] = {"speed=300", stop};
    ASSERT_TRUE(ev3proto::robot::build_behaviour("drive", drive_args, 2, hard, why));
    expect_same(language_plan("drive", {"speed=300", stop}), hard);
  }
  const std::string_view back[] = {"speed=-250"};
  ASSERT_TRUE(ev3proto::robot::build_behaviour("drive", back, 1, hard, why));
  // Backwards neither is interrupted by the forward warnings (the sensors face forward).
  expect_same(language_plan("drive", {"speed=-250"}), hard);
  EXPECT_EQ(hard.steps[0].interrupts, 0);
}

}  // namespace
