/// @file behaviour/print.hpp
/// @brief A Definition written back as text: values, actions and conditions as the language writes
/// them (for messages and drawings), and compact(): the whole behaviour on one line, without comments,
/// the form to send in BEHAVIOUR (';' costs one byte on the wire, a new line three).
///
/// parse(compact(d)) gives a Definition equivalent() to d: the same tables, places aside.
#pragma once

#include <cstdint>
#include <string_view>

#include "definition.hpp"

namespace ev3proto::behaviour {

/// A number in the unit it was written with ("1.5s", "-10cm", "90"), or its word ("red", "brake").
inline void write(Text& out, const Number& n) {
  if (n.dim == Dim::colour) {
    out << to_string(static_cast<Colour>(n.value));
    return;
  }
  if (n.dim == Dim::stop_mode) {
    out << to_string(static_cast<StopAction>(n.value));
    return;
  }
  unsigned decimals = 0;  // the unit's factor is 10^decimals
  for (std::int32_t f = factor_of(n.unit); f > 1; f /= 10) ++decimals;
  char d[2 * kMaxIntText + 2];
  const char* e = write_fixed(d, n.value, decimals, true);
  out << std::string_view(d, static_cast<std::size_t>(e - d)) << to_string(n.unit);
}

/// An argument as written: the constant, or `$name` / `-$name`.
inline void write(Text& out, const Definition& def, const Arg& a) {
  if (a.kind == Arg::Kind::param) {
    out << (a.negate ? "-$" : "$") << def.params[a.param].name.view();
  } else if (a.kind == Arg::Kind::constant) {
    write(out, a.num);
  }
}

/// One step: "drive $distance speed=$turnspeed", "stop hold" (implicit arguments left out, but for
/// stop's brake with @p all).
inline void write(Text& out, const Definition& def, const Step& s, bool all = false) {
  out << to_string(s.action);
  if (s.main.kind != Arg::Kind::none && (!s.main.implicit || (all && s.action == ActionKind::stop))) {
    out << ' ';
    write(out, def, s.main);
  }
  if (s.speed.kind != Arg::Kind::none && !s.speed.implicit) {
    out << " speed=";
    write(out, def, s.speed);
  }
  if (s.halt.kind != Arg::Kind::none && !s.halt.implicit) {
    out << " stop=";
    write(out, def, s.halt);
  }
}

/// A state's action: its step, or "repeat N (step, step)".
inline void write_action(Text& out, const Definition& def, const State& st, std::string_view comma = ", ",
                         bool all = false) {
  if (st.repeat != 1 || st.step_count != 1) {
    out << "repeat " << std::int32_t{st.repeat} << " (";
    for (std::uint8_t k = 0; k < st.step_count; ++k) {
      if (k) out << comma;
      write(out, def, def.steps[st.first_step + k], all);
    }
    out << ')';
  } else {
    write(out, def, def.steps[st.first_step], all);
  }
}

/// What triggers a reaction: "OBSTACLE_DETECTED" or "colour != $colour".
inline void write_trigger(Text& out, const Definition& def, const Reaction& r, bool spaced = true) {
  if (r.trigger == Trigger::event) {
    out << to_string(r.event);
    return;
  }
  out << to_string(r.sensor);
  if (spaced) out << ' ';
  out << to_string(r.op);
  if (spaced) out << ' ';
  write(out, def, r.value);
}

/// A param's value: "2m", "red" or "random 90..270".
inline void write(Text& out, const Param& p) {
  if (p.random) {
    out << "random ";
    write(out, p.lo);
    out << "..";
  }
  write(out, p.random ? p.hi : p.lo);
}

namespace detail {

inline void write_param(Text& out, const Param& p) {
  out << "param " << p.name.view() << '=';
  write(out, p);
}

inline void write_target(Text& out, const Definition& def, std::uint8_t t) {
  out << "->";
  if (t == kIgnore) out << "ignore";
  else out << def.states[t].name.view();
}

/// Reactions [from, to): consecutive events of one target become one `on A,B->t`.
inline void write_reactions(Text& out, const Definition& def, std::uint8_t from, std::uint8_t to) {
  for (std::uint8_t k = from; k < to; ++k) {
    const Reaction& r = def.reactions[k];
    out << ';';
    if (r.trigger == Trigger::condition) {
      out << "when ";
      write_trigger(out, def, r, false);
      write_target(out, def, r.target);
      continue;
    }
    out << "on " << to_string(r.event);
    while (k + 1 < to && def.reactions[k + 1].trigger == Trigger::event && def.reactions[k + 1].target == r.target) {
      ++k;
      out << ',' << to_string(def.reactions[k].event);
    }
    write_target(out, def, r.target);
  }
}

}  // namespace detail

/// The behaviour on one line, statements separated by ';', no comments, no spaces but where two
/// words meet. The stop state is written only when the text defined it.
inline void compact(Text& out, const Definition& def) {
  out << "behaviour " << def.name.view();
  for (std::uint8_t i = 0; i < def.param_count; ++i) {
    out << ';';
    detail::write_param(out, def.params[i]);
  }
  if (def.report.count > 0) {
    out << ";report ";
    for (std::uint8_t i = 0; i < def.report.count; ++i) out << (i ? "," : "") << to_string(def.report.sensors[i]);
    const Number dflt = Report{}.period;
    if (def.report.period.value != dflt.value || def.report.period.unit != dflt.unit) {
      out << " every ";
      write(out, def.report.period);
    }
  }
  detail::write_reactions(out, def, 0, def.global_reactions);
  for (std::uint8_t s = 0; s < def.state_count; ++s) {
    const State& st = def.states[s];
    if (st.implicit) continue;
    out << ";state " << st.name.view() << '=';
    write_action(out, def, st, ",");
    if (st.next != kNone) out << "->" << def.states[st.next].name.view();
    detail::write_reactions(out, def, st.first_reaction,
                            static_cast<std::uint8_t>(st.first_reaction + st.reaction_count));
  }
}

namespace detail {
inline bool same(const Number& a, const Number& b) { return a.value == b.value && a.unit == b.unit && a.dim == b.dim; }
inline bool same(const Arg& a, const Arg& b) {
  return a.kind == b.kind && a.negate == b.negate && a.implicit == b.implicit &&
         (a.kind != Arg::Kind::param || a.param == b.param) && (a.kind != Arg::Kind::constant || same(a.num, b.num));
}
}  // namespace detail

/// Same tables (names, values, transitions, reactions, report), whatever the places.
inline bool equivalent(const Definition& a, const Definition& b) {
  using detail::same;
  if (a.name.view() != b.name.view() || a.param_count != b.param_count || a.state_count != b.state_count ||
      a.step_count != b.step_count || a.reaction_count != b.reaction_count ||
      a.global_reactions != b.global_reactions || a.start != b.start || a.stop != b.stop)
    return false;
  for (std::uint8_t i = 0; i < a.param_count; ++i) {
    const Param &x = a.params[i], &y = b.params[i];
    if (x.name.view() != y.name.view() || x.random != y.random || !same(x.lo, y.lo) || (x.random && !same(x.hi, y.hi)))
      return false;
  }
  for (std::uint8_t i = 0; i < a.state_count; ++i) {
    const State &x = a.states[i], &y = b.states[i];
    if (x.name.view() != y.name.view() || x.repeat != y.repeat || x.first_step != y.first_step ||
        x.step_count != y.step_count || x.next != y.next || x.first_reaction != y.first_reaction ||
        x.reaction_count != y.reaction_count || x.implicit != y.implicit)
      return false;
  }
  for (std::uint8_t i = 0; i < a.step_count; ++i) {
    const Step &x = a.steps[i], &y = b.steps[i];
    if (x.action != y.action || !same(x.main, y.main) || !same(x.speed, y.speed) || !same(x.halt, y.halt)) return false;
  }
  for (std::uint8_t i = 0; i < a.reaction_count; ++i) {
    const Reaction &x = a.reactions[i], &y = b.reactions[i];
    if (x.owner != y.owner || x.trigger != y.trigger || x.target != y.target) return false;
    if (x.trigger == Trigger::event ? x.event != y.event
                                    : (x.sensor != y.sensor || x.op != y.op || !same(x.value, y.value)))
      return false;
  }
  if (a.report.count != b.report.count || !same(a.report.period, b.report.period)) return false;
  for (std::uint8_t i = 0; i < a.report.count; ++i)
    if (a.report.sensors[i] != b.report.sensors[i]) return false;
  return true;
}

}  // namespace ev3proto::behaviour
