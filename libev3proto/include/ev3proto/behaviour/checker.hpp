/// @file behaviour/checker.hpp
/// @brief check(): explores a behaviour's automaton and refuses it, with the place and the path that
/// shows each defect, before it runs (docs/behaviours.md "The checker").
///
/// The automaton's edges: a state's default transition (its action finished), its reactions and the
/// behaviour-wide ones it does not override (events and conditions). An action that fails ends in the
/// stop state whatever the text says (the runtime's rule, ACTION_ERR): that is no edge here, so "a way
/// to the stop state" is one the behaviour declares (`on DEVICE_ERROR -> end` before the first state
/// gives every state one). The normal course is what the start state reaches by default transitions.
/// Rules, in the order they are reported: actions the model lacks, devices the robot lacks, values
/// outside the model's or the language's limits, unreachable states, moving states without a reaction
/// to OBSTACLE_DETECTED or PROXIMITY_ALERT, reactions that never return to the normal course, states
/// with no way to the stop state. A reaction returns when its course (default transitions, conditions
/// and reactions but those to DEVICE_ERROR) reaches the normal course or the stop state.
/// No heap, no exceptions.
#pragma once

#include <cstddef>
#include <cstdint>

#include "definition.hpp"
#include "model.hpp"
#include "print.hpp"

namespace ev3proto::behaviour {

/// Most findings check() keeps (one more sets Findings::more).
inline constexpr std::size_t kMaxFindings = 8;

/// Language limits that are not the model's (the model gives the motors' max_speed).
inline constexpr std::int32_t kMaxDistance = 10000;  ///< mm, one drive (10 m)
inline constexpr std::int32_t kMaxAngle = 3600;      ///< degrees, one turn (ten whole turns)
inline constexpr std::int32_t kMaxPause = 3600000;   ///< ms, one pause (an hour)
inline constexpr std::int32_t kMaxWait = 1000000000; ///< ms, one wait (10^6 s, robot/'s longest wait)
inline constexpr std::int32_t kMaxUltrasonic = 2550; ///< mm, the ultrasonic sensor's range (255 cm)

/// What check() found.
struct Findings {
  Diagnostic items[kMaxFindings];
  std::uint8_t count = 0;
  bool more = false;  ///< more findings than kMaxFindings
  bool ok() const noexcept { return count == 0; }
};

/// The devices a behaviour needs from a robot of model @p model: the drive motors for every action but
/// wait (a pause brakes them first); the sensor of every condition and report; the touch sensor (OBSTACLE_DETECTED) and the
/// ultrasonic sensor (PROXIMITY_ALERT) for a reaction that is not `ignore`, when the model has them (a
/// model without the sensor never raises the event: thesis 6.1.2).
inline std::uint32_t devices_needed(const Definition& def, const Model& model) noexcept {
  std::uint32_t need = 0;
  for (std::uint8_t s = 0; s < def.state_count; ++s) {
    const State& st = def.states[s];
    if (st.implicit) continue;  // the predefined stop state needs nothing: no motors, nothing to stop
    for (std::uint8_t k = 0; k < st.step_count; ++k)
      if (def.steps[st.first_step + k].action != ActionKind::wait) need |= kDriveMotors;
  }
  for (std::uint8_t k = 0; k < def.reaction_count; ++k) {
    const Reaction& r = def.reactions[k];
    if (r.trigger == Trigger::condition) {
      need |= role_bit(device_of(r.sensor));
    } else if (r.target != kIgnore) {
      const Role d = r.event == EventKind::OBSTACLE_DETECTED ? Role::touch
                       : r.event == EventKind::PROXIMITY_ALERT ? Role::ultrasonic
                                                            : Role::gyro;
      if ((r.event == EventKind::OBSTACLE_DETECTED || r.event == EventKind::PROXIMITY_ALERT) && (model.devices & role_bit(d)))
        need |= role_bit(d);
    }
  }
  for (std::uint8_t k = 0; k < def.report.count; ++k) need |= role_bit(device_of(def.report.sensors[k]));
  return need;
}

namespace detail {

/// One hop of a path: the state reached and how (kNone: default transition or the start; else the
/// index of the reaction taken).
struct Hop {
  std::uint8_t state = 0;
  std::uint8_t via = kNone;
};

struct Checker {
  const Definition& def;
  const Model& model;
  std::uint32_t robot;
  Findings& out;

  bool reach[kMaxStates] = {};   // reachable from the start
  bool normal[kMaxStates] = {};  // the normal course
  Hop parent[kMaxStates];        // the BFS tree from the start

  Checker(const Definition& d, const Model& m, std::uint32_t r, Findings& f) noexcept
      : def(d), model(m), robot(r), out(f) {}

  template <typename F>
  void find(Code code, Pos pos, F&& write_message) noexcept {
    if (out.count >= kMaxFindings) {
      out.more = true;
      return;
    }
    MessageWriter w(out.items[out.count++], code, pos);
    write_message(w.text());
  }

  /// Calls f(target, via) for each declared edge out of @p s (via: kNone for the default transition,
  /// else the reaction's index). Reactions to `ignore` are no edge. With @p course, the reactions to
  /// DEVICE_ERROR are left out: an error path is not the course a reaction takes back.
  template <typename F>
  void edges(std::uint8_t s, F&& f, bool course = false) const noexcept {
    if (s == def.stop) return;
    const State& st = def.states[s];
    if (st.next != kNone) f(st.next, kNone);
    auto take = [&](std::uint8_t i) {
      const Reaction& r = def.reactions[i];
      if (r.target == kIgnore || (course && r.trigger == Trigger::event && r.event == EventKind::DEVICE_ERROR)) return;
      f(r.target, i);
    };
    for (std::uint8_t k = 0; k < st.reaction_count; ++k) take(static_cast<std::uint8_t>(st.first_reaction + k));
    for (std::uint8_t i = 0; i < def.global_reactions; ++i) {
      const Reaction& r = def.reactions[i];
      if (r.trigger == Trigger::event && def.on_event(s, r.event) != &r) continue;  // overridden
      take(i);
    }
  }

  /// Marks in @p seen what @p from reaches by declared edges (see edges() for @p course).
  void closure(std::uint8_t from, bool (&seen)[kMaxStates], bool course = false) const noexcept {
    std::uint8_t stack[kMaxStates];
    std::size_t n = 0;
    for (bool& b : seen) b = false;
    seen[from] = true;
    stack[n++] = from;
    while (n > 0) {
      const std::uint8_t s = stack[--n];
      auto visit = [&](std::uint8_t t, std::uint8_t) {
        if (!seen[t]) {
          seen[t] = true;
          stack[n++] = t;
        }
      };
      edges(s, visit, course);
    }
  }

  void explore_from_start() noexcept {
    std::uint8_t queue[kMaxStates];
    std::size_t head = 0, tail = 0;
    reach[def.start] = true;
    parent[def.start] = Hop{def.start, kNone};
    queue[tail++] = def.start;
    while (head < tail) {
      const std::uint8_t s = queue[head++];
      edges(s, [&](std::uint8_t t, std::uint8_t via) {
        if (!reach[t]) {
          reach[t] = true;
          parent[t] = Hop{s, via};
          queue[tail++] = t;
        }
      });
    }
    for (std::uint8_t s = def.start; s != kNone && !normal[s]; s = def.states[s].next) normal[s] = true;
  }

  void write_edge(Text& m, std::uint8_t via) const noexcept {
    if (via == kNone) {
      m << " -> ";
      return;
    }
    m << " -[";
    write_trigger(m, def, def.reactions[via]);
    m << "]-> ";
  }

  /// "start -> ... -> s" along the BFS tree.
  void write_path_to(Text& m, std::uint8_t s) const noexcept {
    Hop hops[kMaxStates];
    std::size_t n = 0;
    for (std::uint8_t t = s; n < kMaxStates; t = parent[t].state) {
      hops[n++] = Hop{t, parent[t].via};
      if (t == def.start) break;
    }
    m << def.states[def.start].name.view();
    for (std::size_t k = n - 1; k-- > 0;) {
      write_edge(m, hops[k].via);
      m << def.states[hops[k].state].name.view();
    }
  }

  /// " -> a -> b": @p s's default transitions until one repeats or a state has none.
  void write_defaults_from(Text& m, std::uint8_t s, bool (&on_path)[kMaxStates]) const noexcept {
    std::uint8_t last = s;
    for (std::uint8_t t = def.states[s].next; t != kNone; t = def.states[t].next) {
      m << " -> " << def.states[t].name.view();
      if (on_path[t] || t == def.stop) return;
      on_path[t] = true;
      last = t;
    }
    if (last != def.stop) m << " (never finishes)";
  }

  void write_set(Text& m, const bool (&set)[kMaxStates]) const noexcept {
    bool first = true;
    for (std::uint8_t s = 0; s < def.state_count; ++s)
      if (set[s]) {
        m << (first ? "" : ", ") << def.states[s].name.view();
        first = false;
      }
  }

  // ---- Rules -----------------------------------------------------------------------------------------

  void model_actions() noexcept {
    for (std::uint8_t s = 0; s < def.state_count; ++s) {
      const State& st = def.states[s];
      if ((st.repeat != 1 || st.step_count != 1) && !(model.actions & bit(ActionKind::repeat)))
        find(Code::model_action, def.steps[st.first_step].pos,
             [&](Text& m) { m << "model " << model.name << " has no action repeat"; });
      for (std::uint8_t k = 0; k < st.step_count; ++k) {
        const Step& step = def.steps[st.first_step + k];
        if (!(model.actions & bit(step.action)) && !(st.implicit))
          find(Code::model_action, step.pos,
               [&](Text& m) { m << "model " << model.name << " has no action " << to_string(step.action); });
      }
    }
  }

  void robot_devices() noexcept {
    const std::uint32_t missing = devices_needed(def, model) & ~robot;
    for (std::uint8_t d = 0; d < robot::kAllRoleCount; ++d) {
      if (!(missing & role_bit(static_cast<Role>(d)))) continue;
      const Role dev = static_cast<Role>(d);
      // The first place that needs it.
      Pos at = def.name_pos;
      char what[48];
      Text w(what, sizeof what);
      bool found = false;
      auto take = [&](Pos p, auto&& name) {
        if (!found || p.line < at.line || (p.line == at.line && p.col < at.col)) {
          at = p;
          w = Text(what, sizeof what);
          name(w);
          found = true;
        }
      };
      for (std::uint8_t k = 0; k < def.step_count; ++k) {
        const Step& s = def.steps[k];
        if (s.action != ActionKind::wait && (kDriveMotors & role_bit(dev)) && s.pos.line != 0)
          take(s.pos, [&](Text& t) { t << to_string(s.action); });
      }
      for (std::uint8_t k = 0; k < def.reaction_count; ++k) {
        const Reaction& r = def.reactions[k];
        if (r.trigger == Trigger::condition && device_of(r.sensor) == dev)
          take(r.pos, [&](Text& t) { t << "when " << to_string(r.sensor); });
        if (r.trigger == Trigger::event && r.target != kIgnore &&
            ((r.event == EventKind::OBSTACLE_DETECTED && dev == Role::touch) ||
             (r.event == EventKind::PROXIMITY_ALERT && dev == Role::ultrasonic)))
          take(r.pos, [&](Text& t) { t << "on " << to_string(r.event); });
      }
      for (std::uint8_t k = 0; k < def.report.count; ++k)
        if (device_of(def.report.sensors[k]) == dev)
          take(def.report.pos, [&](Text& t) { t << "report " << to_string(def.report.sensors[k]); });
      find(Code::robot_device, at, [&](Text& m) {
        m << "the robot has no " << device_name(dev) << " (" << w.view() << " needs it)";
      });
    }
  }

  /// The range a value of slot kind takes, and its name in messages.
  struct Range {
    std::int32_t lo, hi;
    bool nonzero;       // 0 is refused too (a drive or turn of 0 goes nowhere, run 0 stands)
    const char* what;
    const char* unit;   // of lo and hi
    const char* limit;  // where the limit comes from
  };

  void check_value(const Arg& a, const Range& r, std::string_view who, bool (&reported)[kMaxParams]) noexcept {
    if (a.kind == Arg::Kind::none) return;
    std::int32_t lo = 0, hi = 0;
    const Param* p = nullptr;
    if (a.kind == Arg::Kind::param) {
      p = &def.params[a.param];
      if (reported[a.param]) return;
      lo = p->lo.value;
      hi = p->random ? p->hi.value : lo;
    } else {
      lo = hi = a.num.value;
    }
    if (a.negate) {
      const std::int32_t t = lo;
      lo = -hi;
      hi = -t;
    }
    const bool outside = lo < r.lo || hi > r.hi;
    const bool zero = r.nonzero && lo <= 0 && hi >= 0;
    if (!outside && !zero) return;
    if (p != nullptr) reported[a.param] = true;
    find(Code::range, a.pos, [&](Text& m) {
      m << who << ' ' << r.what << ' ';
      if (p != nullptr) {
        m << (a.negate ? "-$" : "$") << p->name.view() << " = ";
        write(m, *p);
      } else {
        write(m, a.num);
      }
      if (outside) m << " is outside " << r.lo << ".." << r.hi << (*r.unit ? " " : "") << r.unit << " (" << r.limit << ")";
      else m << (lo == hi ? " is 0" : " can be 0") << " (" << who << " 0 does nothing)";
    });
  }

  void ranges() noexcept {
    bool reported[kMaxParams] = {};
    char limit[64];
    Text lt(limit, sizeof limit - 1);
    lt << "model " << model.name << "'s max_speed";
    limit[lt.size()] = '\0';
    const Range speed{1, model.max_speed, false, "speed", "deg/s", limit};
    const Range run_speed{-model.max_speed, model.max_speed, true, "speed", "deg/s", limit};
    const Range distance{-kMaxDistance, kMaxDistance, true, "distance", "mm", "a drive is at most 10 m"};
    const Range angle{-kMaxAngle, kMaxAngle, true, "angle", "degrees", "a turn is at most ten whole turns"};
    const Range pause{1, kMaxPause, false, "duration", "ms", "a pause lasts 1 ms to an hour"};
    const Range wait{1, kMaxWait, false, "duration", "ms", "a wait lasts 1 ms to 10^6 s"};
    for (std::uint8_t k = 0; k < def.step_count; ++k) {
      const Step& s = def.steps[k];
      const std::string_view who = to_string(s.action);
      switch (s.action) {
        case ActionKind::run: check_value(s.main, run_speed, who, reported); break;
        case ActionKind::drive:
          check_value(s.main, distance, who, reported);
          check_value(s.speed, speed, who, reported);
          break;
        case ActionKind::turn:
          check_value(s.main, angle, who, reported);
          check_value(s.speed, speed, who, reported);
          break;
        case ActionKind::pause: check_value(s.main, pause, who, reported); break;
        case ActionKind::wait: check_value(s.main, wait, who, reported); break;
        case ActionKind::stop: case ActionKind::repeat: break;
      }
    }
    for (std::uint8_t k = 0; k < def.reaction_count; ++k) {
      const Reaction& r = def.reactions[k];
      if (r.trigger != Trigger::condition) continue;
      if (r.sensor == Sensor::distance)
        check_value(r.value, Range{0, kMaxUltrasonic, false, "distance", "mm", "the ultrasonic sensor's range"},
                    "when", reported);
      if (r.sensor == Sensor::touch)
        check_value(r.value, Range{0, 1, false, "touch", "", "released or pressed"}, "when", reported);
    }
    const std::int32_t period = def.report.period.value;
    if (def.report.count > 0 && (period < kMinReportPeriod || period > kMaxReportPeriod))
      find(Code::range, def.report.pos, [&](Text& m) {
        m << "report every ";
        write(m, def.report.period);
        m << " is outside " << kMinReportPeriod << ".." << kMaxReportPeriod << " ms";
      });
  }

  void unreachable() noexcept {
    for (std::uint8_t s = 0; s < def.state_count; ++s) {
      if (reach[s] || s == def.stop) continue;
      find(Code::unreachable, def.states[s].pos, [&](Text& m) {
        m << "state " << def.states[s].name.view() << " is unreachable from the start state "
          << def.states[def.start].name.view() << " (reachable: ";
        write_set(m, reach);
        m << ")";
      });
    }
  }

  void unguarded() noexcept {
    for (std::uint8_t s = 0; s < def.state_count; ++s) {
      if (!reach[s] || s == def.stop || !def.moves(s)) continue;
      for (const EventKind e : {EventKind::OBSTACLE_DETECTED, EventKind::PROXIMITY_ALERT}) {
        if (def.on_event(s, e) != nullptr) continue;
        find(Code::unguarded, def.states[s].pos, [&](Text& m) {
          m << "state " << def.states[s].name.view() << " moves but has no reaction to " << to_string(e) << ": ";
          write_path_to(m, s);
        });
      }
    }
  }

  void no_return() noexcept {
    for (std::uint8_t i = 0; i < def.reaction_count; ++i) {
      const Reaction& r = def.reactions[i];
      if (r.target == kIgnore) continue;
      // A source the reaction applies to, reachable from the start.
      std::uint8_t source = kNone;
      if (r.owner != kEveryState) {
        if (reach[r.owner]) source = r.owner;
      } else {
        for (std::uint8_t s = 0; s < def.state_count && source == kNone; ++s)
          if (reach[s] && s != def.stop && (r.trigger == Trigger::condition || def.on_event(s, r.event) == &r))
            source = s;
      }
      if (source == kNone) continue;
      bool seen[kMaxStates];
      closure(r.target, seen, true);
      bool back = seen[def.stop];
      for (std::uint8_t s = 0; s < def.state_count; ++s) back = back || (seen[s] && normal[s]);
      if (back) continue;
      find(Code::no_return, r.pos, [&](Text& m) {
        m << "the reaction to ";
        write_trigger(m, def, r);
        m << " never returns to the normal course (";
        write_set(m, normal);
        m << "): ";
        write_path_to(m, source);
        write_edge(m, i);
        m << def.states[r.target].name.view();
        bool on_path[kMaxStates] = {};
        on_path[r.target] = true;
        write_defaults_from(m, r.target, on_path);
      });
    }
  }

  void no_stop() noexcept {
    bool reported[kMaxStates] = {};
    for (std::uint8_t s = 0; s < def.state_count; ++s) {
      if (!reach[s] || s == def.stop || reported[s]) continue;
      bool seen[kMaxStates];
      closure(s, seen);
      if (seen[def.stop]) continue;
      for (std::uint8_t t = 0; t < def.state_count; ++t) reported[t] = reported[t] || seen[t];
      find(Code::no_stop, def.states[s].pos, [&](Text& m) {
        m << "state " << def.states[s].name.view() << " has no way to the stop state " << def.states[def.stop].name.view()
          << ": ";
        write_path_to(m, s);
        bool on_path[kMaxStates] = {};
        on_path[s] = true;
        write_defaults_from(m, s, on_path);
        m << " (from " << def.states[s].name.view() << " only ";
        write_set(m, seen);
        m << "; `on DEVICE_ERROR -> end` before the first state gives every state one)";
      });
    }
  }
};

}  // namespace detail

/// Checks @p def for a robot of model @p model whose plugged devices are @p robot_devices (bit(Device);
/// model.devices when all are plugged). True when nothing was found; otherwise @p out lists the
/// findings in rule order, each with its place and, for the automaton's rules, the path.
inline bool check(const Definition& def, const Model& model, std::uint32_t robot_devices, Findings& out) noexcept {
  out = Findings{};
  detail::Checker c(def, model, robot_devices, out);
  c.explore_from_start();
  c.model_actions();
  c.robot_devices();
  c.ranges();
  c.unreachable();
  c.unguarded();
  c.no_return();
  c.no_stop();
  return out.ok();
}

/// check() for a robot with every device of its model plugged.
inline bool check(const Definition& def, const Model& model, Findings& out) noexcept {
  return check(def, model, model.devices, out);
}

}  // namespace ev3proto::behaviour
