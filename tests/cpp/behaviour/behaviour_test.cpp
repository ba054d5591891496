// The behaviour language: transcripts (tests/cpp/testdata/behaviour_*.txt, see transcript.hpp), the
// built-ins (embedded = behaviours/*.bhv, accepted by the checker, through the wire within 4096 bytes),
// the limits, BEHAVIOUR arguments and what the runtime reads (on_event, condition, value, holds).
// EV3_REWRITE=1 rewrites the transcripts' expectations instead of checking them.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "check_file.hpp"
#include "ev3proto/behaviour/builtins.hpp"
#include "ev3proto/behaviour/checker.hpp"
#include "ev3proto/behaviour/dot.hpp"
#include "ev3proto/behaviour/parser.hpp"
#include "ev3proto/behaviour/print.hpp"
#include "ev3proto/wire.hpp"
#include "transcript.hpp"

namespace {

using namespace ev3proto::behaviour;

class BehaviourTranscript : public ::testing::TestWithParam<std::string> {};

TEST_P(BehaviourTranscript, Matches) {
  bhvtest::check_file(GetParam(), [](const datadriven::Case& c) { return bhvtest::run_case(c.input); });
}

INSTANTIATE_TEST_SUITE_P(Testdata, BehaviourTranscript,
                         ::testing::ValuesIn(bhvtest::transcripts("behaviour_", "behaviour_cli")), bhvtest::name_of);

TEST(BehaviourTranscripts, OneFilePerDefectClass) {
  const std::vector<std::string> files = bhvtest::transcripts("behaviour_", "behaviour_cli");
  for (const char* want : {"behaviour_syntax", "behaviour_meaning", "behaviour_constructs", "behaviour_check_model",
                           "behaviour_check_devices", "behaviour_check_range", "behaviour_check_unreachable",
                           "behaviour_check_unguarded", "behaviour_check_no_return", "behaviour_check_no_stop"}) {
    const bool found = std::any_of(files.begin(), files.end(), [&](const std::string& f) {
      return std::filesystem::path(f).stem().string() == want;
    });
    EXPECT_TRUE(found) << want << ".txt is missing";
  }
}

std::string read(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// ---- Built-ins -------------------------------------------------------------------------------------

TEST(Builtins, AreTheFilesOfBehavioursDir) {
  std::set<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(EV3_BEHAVIOURS_DIR))
    if (e.path().extension() == ".bhv") files.insert(e.path().stem().string());
  std::set<std::string> embedded;
  for (const Builtin& b : kBuiltins) {
    embedded.insert(std::string(b.name));
    EXPECT_EQ(read(std::filesystem::path(EV3_BEHAVIOURS_DIR) / (std::string(b.name) + ".bhv")), b.text) << b.name;
  }
  EXPECT_EQ(files, embedded);
  for (const char* n : {"explore", "exploit", "drive", "wait"}) EXPECT_NE(find_builtin(n), nullptr) << n;
  EXPECT_EQ(find_builtin("nope"), nullptr);
}

TEST(Builtins, ParseAndCheckOnModelA) {
  for (const Builtin& b : kBuiltins) {
    static Definition d;
    Diagnostic g;
    ASSERT_TRUE(parse(b.text, d, g)) << b.name << ": " << bhvtest::diag_line(g);
    EXPECT_EQ(d.name.view(), b.name);
    Findings f;
    EXPECT_TRUE(check(d, kModelA, f)) << b.name << ": " << bhvtest::diag_line(f.items[0]);
  }
}

// A BEHAVIOUR custom datagram with the longest header, through encode and decode: within 4096 bytes,
// the same text back, the same tables parsed from it; the same for the compact form.
TEST(Builtins, RoundTripThroughTheWire) {
  for (const Builtin& b : kBuiltins) {
    static Definition d;
    Diagnostic g;
    ASSERT_TRUE(parse(b.text, d, g));
    const std::string compact_text = bhvtest::with_text([&](Text& t) { compact(t, d); });
    for (const std::string& text : {std::string(b.text), compact_text}) {
      ev3proto::Message m(1, 49999, 4294967295u, ev3proto::MsgType::BEHAVIOUR);
      ASSERT_TRUE(m.add_param("custom"));
      ASSERT_TRUE(m.add_param(text));
      static char buf[ev3proto::kMaxDatagram];
      const ev3proto::EncodeResult e = ev3proto::encode(m, buf, sizeof buf);
      ASSERT_TRUE(e.ok()) << b.name;
      EXPECT_LE(e.size, ev3proto::kMaxDatagram);
      static ev3proto::Message back;
      ASSERT_TRUE(ev3proto::decode(std::string_view(buf, e.size), back).ok()) << b.name;
      ASSERT_EQ(back.param(1), text);
      static Definition again;
      ASSERT_TRUE(parse(back.param(1), again, g)) << bhvtest::diag_line(g);
      EXPECT_TRUE(equivalent(d, again)) << b.name;
    }
    // On the wire the compact form costs less than half the commented file.
    EXPECT_LT(ev3proto::escaped_size(compact_text) * 2, ev3proto::escaped_size(b.text)) << b.name;
  }
}

TEST(Builtins, DotDrawsEveryStateAndTransition) {
  static Definition d;
  Diagnostic g;
  ASSERT_TRUE(parse(find_builtin("explore")->text, d, g));
  const std::string dot = bhvtest::with_text([&](Text& t) { to_dot(t, d); });
  EXPECT_NE(dot.find("\"end\" [label=\"end\\nstop brake\\n(also after a failed action)\", shape=doubleoctagon"),
            std::string::npos);
  EXPECT_NE(dot.find("\"forward\" -> \"bumped\" [style=dashed, label=\"OBSTACLE_DETECTED\"];"), std::string::npos);
  EXPECT_NE(dot.find("\"forward\" -> \"rest\";"), std::string::npos);
  EXPECT_NE(dot.find("ignores PROXIMITY_ALERT, OBSTACLE_DETECTED"), std::string::npos);
  EXPECT_NE(dot.find("_start -> \"forward\""), std::string::npos);
}

// ---- docs/behaviours.md ------------------------------------------------------------------------------

// Every ```bhv block of the page parses and checks; a block that is a built-in's text is that text.
TEST(Docs, ExamplesParseAndCheck) {
  std::istringstream page(read(EV3_DOCS_BEHAVIOURS));
  std::vector<std::string> blocks;
  std::string indent, block;
  bool in = false;
  for (std::string line; std::getline(page, line);) {
    const std::size_t at = line.find_first_not_of(' ');
    const std::string body = at == std::string::npos ? "" : line.substr(at);
    if (!in && body == "```bhv") {
      in = true;
      indent = line.substr(0, at);
      block.clear();
    } else if (in && body == "```") {
      in = false;
      blocks.push_back(block);
    } else if (in) {
      block += (line.rfind(indent, 0) == 0 ? line.substr(indent.size()) : line) + "\n";
    }
  }
  EXPECT_GE(blocks.size(), 7u);
  std::size_t builtins = 0;
  for (const std::string& b : blocks) {
    static Definition d;
    Diagnostic g;
    ASSERT_TRUE(parse(b, d, g)) << bhvtest::diag_line(g) << "\n" << b;
    Findings f;
    EXPECT_TRUE(check(d, kModelA, f)) << bhvtest::diag_line(f.items[0]) << "\n" << b;
    const Builtin* builtin = find_builtin(d.name.view());
    if (builtin != nullptr && b.rfind("# " + std::string(builtin->name) + ":", 0) == 0) {
      EXPECT_EQ(b, builtin->text) << "docs/behaviours.md shows an old " << builtin->name;
      ++builtins;
    }
  }
  EXPECT_EQ(builtins, 3u);  // drive, explore, wait
}

// ---- Limits ----------------------------------------------------------------------------------------

std::string states_text(int n) {
  std::string t = "behaviour many\n";
  for (int i = 0; i < n; ++i) t += "state s" + std::to_string(i) + " = pause 1s -> s" + std::to_string((i + 1) % n) + "\n";
  return t;
}

TEST(Limits, StatesUpToTheTableThenARefusal) {
  static Definition d;
  Diagnostic g;
  ASSERT_TRUE(parse(states_text(kMaxStates - 1), d, g)) << bhvtest::diag_line(g);  // + end
  EXPECT_EQ(d.state_count, kMaxStates);
  EXPECT_FALSE(parse(states_text(kMaxStates), d, g));
  EXPECT_EQ(bhvtest::diag_line(g), "limit: line 33 col 7: too many states (at most 32, end included)");
}

TEST(Limits, TheTextUpToItsMaximum) {
  static Definition d;
  Diagnostic g;
  std::string t = "behaviour big\nstate a = pause 1s -> end\n#";
  t.resize(kMaxSource, 'x');
  EXPECT_TRUE(parse(t, d, g)) << bhvtest::diag_line(g);
  t.push_back('x');
  EXPECT_FALSE(parse(t, d, g));
  EXPECT_EQ(bhvtest::diag_line(g), "limit: the definition is 4097 bytes, more than 4096");
}

TEST(Limits, ReactionsStepsAndParams) {
  static Definition d;
  Diagnostic g;
  std::string t = "behaviour r\n";
  for (std::size_t i = 0; i <= kMaxParams; ++i) t += "param p" + std::to_string(i) + " = 1\n";
  EXPECT_FALSE(parse(t + "state a = pause 1s -> end", d, g));
  EXPECT_EQ(bhvtest::diag_line(g), "limit: line 18 col 7: too many params (at most 16)");

  t = "behaviour r\nstate a = pause 1s -> end\n";
  for (std::size_t i = 0; i < kMaxReactions; ++i) t += "when touch = 1 -> end\n";
  EXPECT_TRUE(parse(t, d, g)) << bhvtest::diag_line(g);
  EXPECT_FALSE(parse(t + "when touch = 1 -> end", d, g));
  EXPECT_EQ(bhvtest::diag_line(g), "limit: line 67 col 6: too many reactions (at most 64)");

  t = "behaviour r\n";
  for (int s = 0; s < 9; ++s)
    t += "state s" + std::to_string(s) + " = repeat 2 (pause 1s, pause 1s, pause 1s, pause 1s, pause 1s, pause 1s, "
         "pause 1s, pause 1s) -> end\n";
  EXPECT_FALSE(parse(t, d, g));
  EXPECT_EQ(bhvtest::diag_line(g), "limit: line 10 col 22: too many actions (at most 64)");
}

// CR LF line ends count as one line end (files written on Windows); a lone CR is refused.
TEST(Text, CrLfLineEnds) {
  static Definition d;
  Diagnostic g;
  EXPECT_TRUE(parse("behaviour x\r\nstate a = wait 1s -> end   # done\r\n", d, g)) << bhvtest::diag_line(g);
  EXPECT_FALSE(parse("behaviour x\r\nstate a = wait 1s -> nowhere\r\n", d, g));
  EXPECT_EQ(bhvtest::diag_line(g), "meaning: line 2 col 22: unknown state 'nowhere'");
  EXPECT_FALSE(parse("behaviour x\rstate a = wait 1s -> end", d, g));
  EXPECT_EQ(bhvtest::diag_line(g),
            "syntax: line 1 col 12: expected the end of the statement (';' or a new line), found byte 0x0D");
}

// ---- BEHAVIOUR arguments ---------------------------------------------------------------------------

TEST(Args, AUnitlessNumberTakesTheParamsUnit) {
  static Definition d;
  Diagnostic g;
  ASSERT_TRUE(parse(find_builtin("wait")->text, d, g));
  const std::string_view a[] = {"seconds=2.5"};
  ASSERT_TRUE(apply_args(d, a, 1, g)) << bhvtest::diag_line(g);
  EXPECT_EQ(d.params[0].lo.value, 2500);
  const std::string_view b[] = {"seconds=300ms"};
  ASSERT_TRUE(apply_args(d, b, 1, g));
  EXPECT_EQ(d.params[0].lo.value, 300);
  const std::string_view c[] = {"seconds=2cm"};
  EXPECT_FALSE(apply_args(d, c, 1, g));
  EXPECT_EQ(bhvtest::diag_line(g), "meaning: argument 'seconds=2cm': seconds takes a duration, not '2cm'");
}

TEST(Args, RandomAndFixedAngles) {
  static Definition d;
  Diagnostic g;
  ASSERT_TRUE(parse(find_builtin("explore")->text, d, g));
  const std::uint8_t angle = d.find_param("angle");
  const std::string_view fixed[] = {"angle=90", "seed=7"};
  ASSERT_TRUE(apply_args(d, fixed, 2, g)) << bhvtest::diag_line(g);
  EXPECT_FALSE(d.params[angle].random);
  EXPECT_EQ(d.params[angle].lo.value, 90);
  EXPECT_EQ(d.seed(), 7u);
  const std::string_view bare[] = {"angle=random"};
  EXPECT_FALSE(apply_args(d, bare, 1, g));  // now fixed: a range is needed
  EXPECT_EQ(bhvtest::diag_line(g), "meaning: argument 'angle=random': random needs a range here: random LO..HI");
  const std::string_view range[] = {"angle=random 45..135"};
  ASSERT_TRUE(apply_args(d, range, 1, g)) << bhvtest::diag_line(g);
  EXPECT_TRUE(d.params[angle].random);
  EXPECT_EQ(d.params[angle].hi.value, 135);
  const std::string_view unknown[] = {"sped=3"};
  EXPECT_FALSE(apply_args(d, unknown, 1, g));
  EXPECT_EQ(bhvtest::diag_line(g),
            "meaning: argument 'sped=3': unknown param 'sped' (params: speed, distance, angle, turnspeed, backoff, "
            "settle, seed)");
}

// An angle param whose unit only one end of its range carries: an argument without a unit keeps the
// angle, and the compact form reads back to the same tables (found by fuzz_behaviour).
TEST(Args, AnAngleArgumentSurvivesTheCompactForm) {
  static Definition d, again;
  Diagnostic g;
  ASSERT_TRUE(parse("behaviour t\nparam angle = random 90..270deg\nstate s = turn $angle speed=100 -> end\n", d, g))
      << bhvtest::diag_line(g);
  for (const std::string_view a : {"angle=random 1..2", "angle=45"}) {
    ASSERT_TRUE(apply_args(d, &a, 1, g)) << bhvtest::diag_line(g);
    EXPECT_EQ(d.params[0].lo.dim, Dim::angle) << a;
    const std::string text = bhvtest::with_text([&](Text& t) { compact(t, d); });
    ASSERT_TRUE(parse(text, again, g)) << text << ": " << bhvtest::diag_line(g);
    EXPECT_TRUE(equivalent(d, again)) << a << " -> " << text;
  }
}

// ---- What the runtime reads ------------------------------------------------------------------------

TEST(Runtime, ReactionsConditionsAndValues) {
  static Definition d;
  Diagnostic g;
  ASSERT_TRUE(parse("behaviour r\nparam speed = 300\nparam c = green\nparam a = random 10..20\n"
                    "on OBSTACLE_DETECTED -> b\nwhen distance < 30cm -> b\n"
                    "state f = run\non OBSTACLE_DETECTED -> ignore\non PROXIMITY_ALERT -> b\nwhen colour != $c -> b\n"
                    "state b = turn $a -> f\non PROXIMITY_ALERT -> ignore",
                    d, g))
      << bhvtest::diag_line(g);
  const std::uint8_t f = d.find_state("f"), b = d.find_state("b");
  // The state's own reaction first, else the behaviour-wide one; ignore is a reaction.
  EXPECT_EQ(d.on_event(f, EventKind::OBSTACLE_DETECTED)->target, kIgnore);
  EXPECT_EQ(d.on_event(b, EventKind::OBSTACLE_DETECTED)->target, b);
  EXPECT_EQ(d.on_event(f, EventKind::PROXIMITY_ALERT)->target, b);
  EXPECT_EQ(d.on_event(f, EventKind::DEVICE_CONNECTED), nullptr);
  EXPECT_EQ(d.on_event(d.stop, EventKind::OBSTACLE_DETECTED), nullptr);
  // Conditions: the state's, then the behaviour-wide ones.
  ASSERT_NE(d.condition(f, 0), nullptr);
  EXPECT_EQ(d.condition(f, 0)->sensor, Sensor::colour);
  EXPECT_EQ(d.condition(f, 1)->sensor, Sensor::distance);
  EXPECT_EQ(d.condition(f, 2), nullptr);
  EXPECT_EQ(d.condition(b, 0)->sensor, Sensor::distance);
  EXPECT_TRUE(d.holds(*d.condition(f, 0), static_cast<std::int32_t>(Colour::red)));
  EXPECT_FALSE(d.holds(*d.condition(f, 0), static_cast<std::int32_t>(Colour::green)));
  EXPECT_TRUE(d.holds(*d.condition(f, 1), 299));
  EXPECT_FALSE(d.holds(*d.condition(f, 1), 300));
  // run's speed is the param speed; the turn's angle is drawn from the seeded generator.
  Rng rng(d.seed());
  EXPECT_EQ(d.value(d.steps[d.states[f].first_step].main, rng), 300);
  Rng again(d.seed());
  std::set<std::int32_t> seen;
  for (int i = 0; i < 200; ++i) {
    const std::int32_t v = d.value(d.steps[d.states[b].first_step].main, rng);
    EXPECT_EQ(v, d.value(d.steps[d.states[b].first_step].main, again));  // same seed, same draws
    EXPECT_GE(v, 10);
    EXPECT_LE(v, 20);
    seen.insert(v);
  }
  EXPECT_EQ(seen.size(), 11u);
  EXPECT_TRUE(d.moves(f));
  EXPECT_TRUE(d.moves(b));
}

TEST(Runtime, NegatedParamsAndRepeat) {
  static Definition d;
  Diagnostic g;
  ASSERT_TRUE(parse("behaviour r;param speed = 300;param back = 10cm;"
                    "state a = repeat 3 (drive -$back, pause 1s) -> end", d, g))
      << bhvtest::diag_line(g);
  const State& a = d.states[0];
  EXPECT_EQ(a.repeat, 3);
  EXPECT_EQ(a.step_count, 2);
  Rng rng;
  EXPECT_EQ(d.value(d.steps[a.first_step].main, rng), -100);
  EXPECT_EQ(d.value(d.steps[a.first_step].speed, rng), 300);
  EXPECT_EQ(d.steps[a.first_step + 1].action, ActionKind::pause);
  EXPECT_EQ(d.value(d.steps[a.first_step + 1].main, rng), 1000);
}

TEST(Devices, NeededByModelA) {
  static Definition d;
  Diagnostic g;
  ASSERT_TRUE(parse(find_builtin("explore")->text, d, g));  // it reports the colour too
  EXPECT_EQ(devices_needed(d, kModelA),
            kDriveMotors | role_bit(Role::touch) | role_bit(Role::ultrasonic) | role_bit(Role::colour));
  ASSERT_TRUE(parse(find_builtin("exploit")->text, d, g));
  EXPECT_EQ(devices_needed(d, kModelA),
            kDriveMotors | role_bit(Role::touch) | role_bit(Role::ultrasonic) | role_bit(Role::colour));
  ASSERT_TRUE(parse(find_builtin("wait")->text, d, g));
  EXPECT_EQ(devices_needed(d, kModelA), 0u);
  // A model without an ultrasonic sensor never raises PROXIMITY_ALERT: reacting to it needs nothing.
  ASSERT_TRUE(parse(find_builtin("drive")->text, d, g));
  Model no_us = kModelA;
  no_us.devices &= ~role_bit(Role::ultrasonic);
  EXPECT_EQ(devices_needed(d, no_us), kDriveMotors | role_bit(Role::touch));
}

}  // namespace
