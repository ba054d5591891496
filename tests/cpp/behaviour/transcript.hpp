// The behaviour language's transcript commands (tests/cpp/testdata/behaviour_*.txt), shared by the
// native and armel tests. A case's first input line is the command, the other lines the definition:
//
//   parse                    the tables it parses into (dump below), or the error
//   check [OPTION]...        the checker's findings, or ok. Options: --without ROLE (the robot lacks
//                            the device: left, right, ultrasonic, touch, colour, gyro), --lacks ACTION
//                            (the model lacks it), --set KEY=VALUE (a BEHAVIOUR argument)
//   compact                  the one-line form, and whether it parses back to the same tables
//
// Errors and findings are written `<code>: line L col C: message`.
#pragma once

#include <sstream>
#include <string>
#include <vector>

#include "ev3proto/behaviour/checker.hpp"
#include "ev3proto/behaviour/parser.hpp"
#include "ev3proto/behaviour/print.hpp"

namespace bhvtest {

using namespace ev3proto::behaviour;

inline const char* code_name(Code c) {
  switch (c) {
    case Code::syntax: return "syntax";
    case Code::meaning: return "meaning";
    case Code::limit: return "limit";
    case Code::range: return "range";
    case Code::model_action: return "model_action";
    case Code::robot_device: return "robot_device";
    case Code::unreachable: return "unreachable";
    case Code::unguarded: return "unguarded";
    case Code::no_return: return "no_return";
    case Code::no_stop: return "no_stop";
  }
  return "?";
}

inline std::string diag_line(const Diagnostic& d) {
  char buf[kMaxMessage + 64];
  Text t(buf, sizeof buf);
  t << code_name(d.code) << ": ";
  write(t, d);
  return std::string(t.view());
}

template <typename F>
std::string with_text(F&& f) {
  static char buf[1 << 14];
  Text t(buf, sizeof buf);
  f(t);
  return std::string(t.view());
}

/// The tables of a definition, one construct a line.
inline std::string dump(const Definition& d) {
  std::ostringstream o;
  o << "behaviour " << d.name.view() << " (start " << d.states[d.start].name.view() << ", stop "
    << d.states[d.stop].name.view() << ")\n";
  for (std::uint8_t i = 0; i < d.param_count; ++i) {
    const Param& p = d.params[i];
    o << "param " << p.name.view() << " = " << with_text([&](Text& t) { write(t, p); }) << " ("
      << (p.random ? "random " : "") << "value " << p.lo.value;
    if (p.random) o << ".." << p.hi.value;
    o << ")\n";
  }
  if (d.report.count > 0) {
    o << "report";
    for (std::uint8_t i = 0; i < d.report.count; ++i) o << (i ? ", " : " ") << to_string(d.report.sensors[i]);
    o << " every " << d.report.period.value << " ms\n";
  }
  auto reactions = [&](std::uint8_t from, std::uint8_t n, const char* indent) {
    for (std::uint8_t k = 0; k < n; ++k) {
      const Reaction& r = d.reactions[from + k];
      o << indent << (r.trigger == Trigger::event ? "on " : "when ")
        << with_text([&](Text& t) { write_trigger(t, d, r); }) << " -> "
        << (r.target == kIgnore ? std::string("ignore") : std::string(d.states[r.target].name.view())) << "\n";
    }
  };
  reactions(0, d.global_reactions, "every state: ");
  for (std::uint8_t s = 0; s < d.state_count; ++s) {
    const State& st = d.states[s];
    // Each step as written, and the speed it takes from the param speed when it names none.
    o << "state " << st.name.view() << " = ";
    const bool repeat = st.repeat != 1 || st.step_count != 1;
    if (repeat) o << "repeat " << st.repeat << " (";
    for (std::uint8_t k = 0; k < st.step_count; ++k) {
      const Step& step = d.steps[st.first_step + k];
      o << (k ? ", " : "") << with_text([&](Text& t) { write(t, d, step, true); });
      const Arg& speed = step.action == ActionKind::run ? step.main : step.speed;
      if (speed.implicit) o << " [speed $" << d.params[speed.param].name.view() << "]";
    }
    if (repeat) o << ")";
    if (st.next != kNone) o << " -> " << d.states[st.next].name.view();
    if (st.implicit) o << " (implicit)";
    o << "\n";
    reactions(st.first_reaction, st.reaction_count, "  ");
  }
  return o.str();
}

inline bool device_named(const std::string& n, Role& d) {
  for (std::uint8_t k = 0; k < ev3proto::robot::kAllRoleCount; ++k)
    if (to_string(static_cast<Role>(k)) == n) {
      d = static_cast<Role>(k);
      return true;
    }
  return false;
}

/// Runs one case; returns its output lines.
inline std::string run_case(const std::vector<std::string>& input) {
  if (input.empty()) return "bad case: no command\n";
  std::istringstream cmd(input[0]);
  std::string verb;
  cmd >> verb;
  std::string text;
  for (std::size_t i = 1; i < input.size(); ++i) text += input[i] + (i + 1 < input.size() ? "\n" : "");
  static Definition def;
  Diagnostic diag;
  if (!parse(text, def, diag)) return diag_line(diag) + "\n";
  if (verb == "parse") return dump(def);
  if (verb == "compact") {
    const std::string line = with_text([&](Text& t) { compact(t, def); });
    static Definition again;
    const bool back = parse(line, again, diag) && equivalent(def, again);
    return line + "\n" + (back ? "parses back to the same tables\n" : "DOES NOT parse back: " + diag_line(diag) + "\n");
  }
  if (verb != "check") return "bad case: unknown command " + verb + "\n";
  Model model = kModelA;
  std::uint32_t robot = model.devices;
  std::vector<std::string> sets;
  for (std::string opt, val; cmd >> opt >> val;) {
    if (opt == "--set") {
      sets.push_back(val);
    } else if (opt == "--without") {
      Role dev;
      if (!device_named(val, dev)) return "bad case: unknown device " + val + "\n";
      robot &= ~role_bit(dev);
    } else if (opt == "--lacks") {
      std::uint8_t a = 0;
      while (a < kActionCount && to_string(static_cast<ActionKind>(a)) != val) ++a;
      if (a == kActionCount) return "bad case: unknown action " + val + "\n";
      model.actions &= ~bit(static_cast<ActionKind>(a));
    } else {
      return "bad case: unknown option " + opt + "\n";
    }
  }
  std::vector<std::string_view> args(sets.begin(), sets.end());
  if (!apply_args(def, args.data(), args.size(), diag)) return diag_line(diag) + "\n";
  Findings f;
  if (check(def, model, robot, f)) return "ok\n";
  std::string out;
  for (std::uint8_t k = 0; k < f.count; ++k) out += diag_line(f.items[k]) + "\n";
  if (f.more) out += "(more)\n";
  return out;
}

}  // namespace bhvtest
