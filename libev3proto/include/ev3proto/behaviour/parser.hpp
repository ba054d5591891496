/// @file behaviour/parser.hpp
/// @brief parse(): the text of a behaviour to a Definition, or the first error with its line and
/// column; apply_args(): BEHAVIOUR's key=value arguments over a Definition's params.
///
/// The grammar is grammar.hpp (PEGTL). Its actions here only record tokens (a rule may still be
/// backtracked); the actions of whole constructs (a step, a statement) interpret them, so every
/// error is found where the construct is complete and names its own place. A syntax error is the
/// furthest place a named rule failed, with what was expected there and what was found.
/// No heap, no exceptions: builds with -fno-exceptions -fno-rtti for the robot.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "definition.hpp"
#include "grammar.hpp"

namespace ev3proto::behaviour {

namespace detail {

/// A token as written, with its place.
struct Tok {
  std::string_view text;
  Pos pos;
};

/// An argument as written: a number, `$name` (maybe `-$name`) or a word.
struct RawArg {
  enum class Kind : std::uint8_t { number, param, word };
  Kind kind = Kind::number;
  bool negate = false;
  Tok tok;  ///< for a param: its name without '$'
};

enum class NumError : std::uint8_t { ok, unit, fraction, too_large };

struct UnitInfo {
  std::string_view name;
  Unit unit;
  Dim dim;
  std::int32_t factor;
};
inline constexpr UnitInfo kUnits[] = {
    {"mm", Unit::mm, Dim::distance, 1}, {"cm", Unit::cm, Dim::distance, 10}, {"m", Unit::m, Dim::distance, 1000},
    {"ms", Unit::ms, Dim::duration, 1}, {"s", Unit::s, Dim::duration, 1000}, {"deg", Unit::deg, Dim::angle, 1},
};

/// Parses a number token (sign, digits, fraction, unit letters). A token without a unit takes
/// @p default_unit (Unit::none in the text; a param's unit for BEHAVIOUR arguments).
/// On NumError::unit, @p unit_at is the unit's offset in @p t.
inline NumError parse_number(std::string_view t, Unit default_unit, Number& out, std::size_t& unit_at) noexcept {
  std::size_t i = 0;
  const bool neg = i < t.size() && t[i] == '-';
  if (neg) ++i;
  std::int64_t mant = 0;
  std::int64_t scale = 1;
  bool frac = false;
  bool any = false;
  for (; i < t.size(); ++i) {
    const char c = t[i];
    if (c >= '0' && c <= '9') {
      any = true;
      if (mant > 100000000000LL) return NumError::too_large;
      mant = mant * 10 + (c - '0');
      if (frac) {
        if (scale >= 1000) return NumError::fraction;  // more than three decimals: never whole
        scale *= 10;
      }
    } else if (c == '.' && !frac) {
      frac = true;
    } else {
      break;
    }
  }
  if (!any) return NumError::too_large;
  unit_at = i;
  const std::string_view u = t.substr(i);
  UnitInfo info{"", default_unit, Dim::plain, factor_of(default_unit)};
  if (default_unit != Unit::none) {
    for (const UnitInfo& k : kUnits)
      if (k.unit == default_unit) info = k;
  }
  if (!u.empty()) {
    bool found = false;
    for (const UnitInfo& k : kUnits)
      if (k.name == u) {
        info = k;
        found = true;
      }
    if (!found) return NumError::unit;
  }
  const std::int64_t scaled = mant * info.factor;
  if (scaled % scale != 0) return NumError::fraction;
  const std::int64_t v = scaled / scale;
  if (v > 1000000000LL) return NumError::too_large;
  out.value = static_cast<std::int32_t>(neg ? -v : v);
  out.unit = info.unit;
  out.dim = info.dim;
  return NumError::ok;
}

/// The name of a dimension's base unit ("ms"), for "not a whole number of ms".
constexpr std::string_view base_unit(Dim d) noexcept {
  switch (d) {
    case Dim::distance: return "mm";
    case Dim::duration: return "ms";
    case Dim::angle: return "degrees";
    default: return "units";
  }
}

/// Looks up a word value: a colour or a stop mode.
inline bool word_value(std::string_view w, Number& out) noexcept {
  for (std::uint8_t c = 0; c <= static_cast<std::uint8_t>(Colour::brown); ++c)
    if (to_string(static_cast<Colour>(c)) == w) {
      out = Number{c, Unit::none, Dim::colour};
      return true;
    }
  for (std::uint8_t m = 0; m <= static_cast<std::uint8_t>(StopAction::hold); ++m)
    if (to_string(static_cast<StopAction>(m)) == w) {
      out = Number{m, Unit::none, Dim::stop_mode};
      return true;
    }
  return false;
}

/// A constant the text did not write (stop's brake).
inline Arg implicit_arg(const Number& n, Pos pos) noexcept {
  Arg a;
  a.kind = Arg::Kind::constant;
  a.num = n;
  a.pos = pos;
  a.implicit = true;
  return a;
}

/// What an argument's place takes.
enum class Slot : std::uint8_t { speed, distance, angle, duration, stop_mode, colour, count, touch };

constexpr std::string_view describe(Slot s) noexcept {
  switch (s) {
    case Slot::speed: return "a speed (a plain number, degrees per second)";
    case Slot::distance: return "a distance (mm, cm or m)";
    case Slot::angle: return "an angle (degrees)";
    case Slot::duration: return "a duration (ms or s)";
    case Slot::stop_mode: return "a stop mode (coast, brake or hold)";
    case Slot::colour: return "a colour (none, black, blue, green, yellow, red, white, brown)";
    case Slot::count: return "a whole number";
    case Slot::touch: return "0 or 1";
  }
  return "?";
}

constexpr std::string_view describe(Dim d) noexcept {
  switch (d) {
    case Dim::plain: return "a plain number";
    case Dim::distance: return "a distance";
    case Dim::duration: return "a duration";
    case Dim::angle: return "an angle";
    case Dim::colour: return "a colour";
    case Dim::stop_mode: return "a stop mode";
  }
  return "?";
}

/// Whether a value of dimension @p d fits slot @p s (an angle may be written without `deg`).
constexpr bool fits(Dim d, Slot s) noexcept {
  switch (s) {
    case Slot::speed: case Slot::count: case Slot::touch: return d == Dim::plain;
    case Slot::distance: return d == Dim::distance;
    case Slot::angle: return d == Dim::angle || d == Dim::plain;
    case Slot::duration: return d == Dim::duration;
    case Slot::stop_mode: return d == Dim::stop_mode;
    case Slot::colour: return d == Dim::colour;
  }
  return false;
}

/// Where the parser is and what it has read so far.
struct Parser {
  Parser(std::string_view text, Definition& d, Diagnostic& g) noexcept : src(text), def(d), diag(g) {}

  std::string_view src;
  Definition& def;
  Diagnostic& diag;
  bool failed = false;  // a meaning error is recorded (the first one wins)

  // The furthest failure of a named rule (syntax errors).
  std::size_t far_off = 0;
  Pos far_pos;
  std::uint32_t far_set = 0;
  bool far_any = false;
  struct Start {
    std::size_t off;
    Pos pos;
  };
  Start starts[16];
  std::size_t depth = 0;

  // Statement-wide.
  bool have_header = false;
  bool have_report = false;
  std::uint8_t current = kEveryState;  // the state reactions attach to

  // Registers the token actions fill and the construct actions read.
  RawArg last_arg;
  Tok behaviour_name, param_name, range_lo, range_hi, report_period, repeat_count, state_name,
      next_name, target_name, sensor_name, op;
  bool param_random = false;
  bool has_period = false;
  Tok report_sensors[kMaxReports + 1];
  std::size_t report_count = 0;
  enum class Stmt : std::uint8_t { none, behaviour, param, report, state, on, when };
  Stmt stmt = Stmt::none;  // the statement being read (set by its keyword)
  struct Option {
    Tok name;
    RawArg value;
  };
  /// A step as written (interpreted when its statement is complete).
  struct RawStep {
    Tok action;
    bool has_main = false;
    RawArg main;
    Option options[4];
    std::size_t option_count = 0;
    bool too_many_options = false;
  };
  RawStep step;                              // the step being read
  RawStep raw_steps[kMaxRepeatSteps + 1];    // the statement's steps
  std::size_t raw_step_count = 0;
  bool too_many_steps = false;
  bool has_repeat = false;
  std::uint8_t first_step = 0;
  std::uint16_t repeat = 1;
  bool has_next = false;
  Tok events[kMaxReactions + 1];
  std::size_t event_count = 0;
  bool target_ignore = false;

  // State names to resolve once every state is known.
  struct Ref {
    std::uint8_t* slot;
    Tok name;
  };
  Ref refs[kMaxStates + kMaxReactions];
  std::size_t ref_count = 0;

  static Pos pos_of(std::size_t line, std::size_t col) noexcept {
    return Pos{static_cast<std::uint16_t>(line > 0xFFFF ? 0xFFFF : line),
               static_cast<std::uint16_t>(col > 0xFFFF ? 0xFFFF : col)};
  }

  /// Records the first meaning error; returns false so an action can `return error(...)`.
  template <typename F>
  bool error(Code code, Pos pos, F&& write) noexcept {
    if (failed) return false;
    failed = true;
    MessageWriter w(diag, code, pos);
    write(w.text());
    return false;
  }

  void push(std::size_t off, Pos pos) noexcept {
    if (depth < 16) starts[depth] = Start{off, pos};
    ++depth;
  }
  void pop() noexcept {
    if (depth > 0) --depth;
  }
  void fail_at(grammar::Expect e) noexcept {
    if (depth == 0) return;
    --depth;
    if (depth >= 16) return;
    const Start s = starts[depth];
    if (!far_any || s.off > far_off) {
      far_any = true;
      far_off = s.off;
      far_pos = s.pos;
      far_set = 0;
    }
    if (s.off == far_off) far_set |= std::uint32_t{1} << static_cast<unsigned>(e);
  }

  Pos offset_pos(Pos p, std::size_t cols) const noexcept {
    return Pos{p.line, static_cast<std::uint16_t>(p.col + cols > 0xFFFF ? 0xFFFF : p.col + cols)};
  }

  // ---- Interpreting values --------------------------------------------------------------------

  bool number(const Tok& t, Unit default_unit, Number& out) noexcept {
    std::size_t unit_at = 0;
    switch (parse_number(t.text, default_unit, out, unit_at)) {
      case NumError::ok: return true;
      case NumError::unit:
        return error(Code::meaning, offset_pos(t.pos, unit_at), [&](Text& m) {
          m << "unknown unit '" << t.text.substr(unit_at) << "' (units: mm, cm, m, ms, s, deg)";
        });
      case NumError::fraction: {
        std::string_view unit = t.text;  // the letters at its end
        while (!unit.empty() && !((unit.front() >= 'a' && unit.front() <= 'z') || (unit.front() >= 'A' && unit.front() <= 'Z')))
          unit.remove_prefix(1);
        Dim d = Dim::plain;
        for (const UnitInfo& k : kUnits)
          if (k.name == unit || (unit.empty() && k.unit == default_unit)) d = k.dim;
        return error(Code::meaning, t.pos, [&](Text& m) {
          m << "'" << t.text << "' is not a whole number";
          if (d != Dim::plain) m << " of " << base_unit(d);
        });
      }
      case NumError::too_large:
        return error(Code::limit, t.pos, [&](Text& m) { m << "'" << t.text << "' is too large"; });
    }
    return false;
  }

  /// Interprets @p a for a place that takes @p slot; @p who names the place in messages
  /// ("drive takes ..."). Params must be declared before they are used.
  bool make_arg(const RawArg& a, Slot slot, std::string_view who, Arg& out) noexcept {
    out = Arg{};
    out.pos = a.tok.pos;
    out.negate = a.negate;
    Dim d = Dim::plain;
    if (a.kind == RawArg::Kind::param) {
      const std::uint8_t i = def.find_param(a.tok.text);
      if (i == kNone)
        return error(Code::meaning, a.tok.pos, [&](Text& m) {
          m << "unknown param '" << a.tok.text << "' (a param is declared before it is used)";
        });
      out.kind = Arg::Kind::param;
      out.param = i;
      d = def.params[i].dim();
      if (!fits(d, slot))
        return error(Code::meaning, a.tok.pos, [&](Text& m) {
          m << who << " takes " << describe(slot) << ", not $" << a.tok.text << " (" << describe(d) << ", line "
            << def.params[i].pos.line << ")";
        });
    } else {
      Number n;
      if (a.kind == RawArg::Kind::word) {
        if (!word_value(a.tok.text, n))
          return error(Code::meaning, a.tok.pos, [&](Text& m) {
            m << "unknown value '" << a.tok.text << "' (" << who << " takes " << describe(slot) << ")";
          });
      } else if (!number(a.tok, Unit::none, n)) {
        return false;
      }
      out.kind = Arg::Kind::constant;
      out.num = n;
      d = n.dim;
      if (!fits(d, slot))
        return error(Code::meaning, a.tok.pos, [&](Text& m) {
          m << who << " takes " << describe(slot) << ", not '" << a.tok.text << "'";
          if (d == Dim::plain && (slot == Slot::distance || slot == Slot::duration))
            m << " (write its unit: " << a.tok.text << (slot == Slot::distance ? "mm" : "ms") << ")";
        });
    }
    if (a.negate && (d == Dim::colour || d == Dim::stop_mode))
      return error(Code::meaning, a.tok.pos, [&](Text& m) { m << "-$" << a.tok.text << ": a word cannot be negated"; });
    return true;
  }

  bool name_fits(const Tok& t) noexcept {
    if (t.text.size() <= kMaxName) return true;
    return error(Code::limit, t.pos, [&](Text& m) {
      m << "name '" << t.text.substr(0, kMaxName) << "...' is longer than " << kMaxName << " characters";
    });
  }

  bool header_first(Pos p) noexcept {
    if (have_header) return true;
    return error(Code::meaning, p, [&](Text& m) { m << "a definition starts with 'behaviour NAME'"; });
  }

  bool add_ref(std::uint8_t* slot, const Tok& name) noexcept {
    refs[ref_count++] = Ref{slot, name};
    return true;
  }

  // ---- Constructs ----------------------------------------------------------------------------------

  bool commit_param() noexcept {
    const Tok& n = param_name;
    if (!name_fits(n)) return false;
    const std::uint8_t dup = def.find_param(n.text);
    if (dup != kNone)
      return error(Code::meaning, n.pos, [&](Text& m) {
        m << "param '" << n.text << "' is already declared at line " << def.params[dup].pos.line;
      });
    if (def.param_count >= kMaxParams)
      return error(Code::limit, n.pos, [&](Text& m) { m << "too many params (at most " << kMaxParams << ")"; });
    Param p;
    p.name.set(n.text);
    p.pos = n.pos;
    if (param_random) {
      p.random = true;
      if (!number(range_lo, Unit::none, p.lo) || !number(range_hi, Unit::none, p.hi)) return false;
      if (p.lo.dim == Dim::plain && p.hi.dim == Dim::angle) p.lo.dim = Dim::angle;
      if (p.hi.dim == Dim::plain && p.lo.dim == Dim::angle) p.hi.dim = Dim::angle;
      if (p.lo.dim != p.hi.dim)
        return error(Code::meaning, range_hi.pos, [&](Text& m) {
          m << "the ends of a random range are of one kind: '" << range_lo.text << "' is " << describe(p.lo.dim)
            << ", '" << range_hi.text << "' is " << describe(p.hi.dim);
        });
      if (p.lo.dim == Dim::colour || p.lo.dim == Dim::stop_mode)
        return error(Code::meaning, range_lo.pos, [&](Text& m) { m << "a random range is of numbers"; });
      if (p.lo.value > p.hi.value)
        return error(Code::meaning, range_lo.pos, [&](Text& m) {
          m << "random range " << range_lo.text << ".." << range_hi.text << " is empty (its low end is above its high end)";
        });
    } else if (last_arg.kind == RawArg::Kind::word) {
      if (!word_value(last_arg.tok.text, p.lo))
        return error(Code::meaning, last_arg.tok.pos, [&](Text& m) {
          m << "unknown value '" << last_arg.tok.text
            << "' (a param is a number with its unit, a colour, a stop mode or random LO..HI)";
        });
    } else if (!number(last_arg.tok, Unit::none, p.lo)) {
      return false;
    }
    if (n.text == "seed" && (p.random || p.lo.dim != Dim::plain || p.lo.value < 0))
      return error(Code::meaning, n.pos, [&](Text& m) {
        m << "param seed is the seed of the random params: a whole number 0 or more";
      });
    def.params[def.param_count++] = p;
    return true;
  }

  bool commit_report() noexcept {
    const Pos at = report_sensors[0].pos;
    if (have_report)
      return error(Code::meaning, at, [&](Text& m) {
        m << "report is written twice (first at line " << def.report.pos.line << ")";
      });
    have_report = true;
    def.report.pos = at;
    for (std::size_t k = 0; k < report_count; ++k) {
      const Tok& t = report_sensors[k];
      if (k >= kMaxReports)
        return error(Code::limit, t.pos, [&](Text& m) { m << "too many sensors to report (at most " << kMaxReports << ")"; });
      std::uint8_t s = 0;
      while (s < kSensorCount && to_string(static_cast<Sensor>(s)) != t.text) ++s;
      if (s == kSensorCount)
        return error(Code::meaning, t.pos, [&](Text& m) {
          m << "unknown sensor '" << t.text << "' (sensors: distance, touch, colour, gyro)";
        });
      for (std::uint8_t j = 0; j < def.report.count; ++j)
        if (def.report.sensors[j] == static_cast<Sensor>(s))
          return error(Code::meaning, t.pos, [&](Text& m) { m << "sensor " << t.text << " is reported twice"; });
      def.report.sensors[def.report.count++] = static_cast<Sensor>(s);
    }
    if (has_period) {
      Number n;
      if (!number(report_period, Unit::none, n)) return false;
      if (n.dim != Dim::duration)
        return error(Code::meaning, report_period.pos, [&](Text& m) {
          m << "every takes " << describe(Slot::duration) << ", not '" << report_period.text << "'";
        });
      def.report.period = n;
    }
    return true;
  }

  bool commit_step(const RawStep& raw) noexcept {
    const Tok& a = raw.action;
    const RawArg& main = raw.main;
    const bool has_main = raw.has_main;
    const Option* options = raw.options;
    const std::size_t option_count = raw.option_count;
    std::uint8_t k = 0;
    while (k < kActionCount && to_string(static_cast<ActionKind>(k)) != a.text) ++k;
    if (k == kActionCount || static_cast<ActionKind>(k) == ActionKind::repeat)
      return error(Code::meaning, a.pos, [&](Text& m) {
        m << "unknown action '" << a.text << "' (actions: run, drive, turn, stop, pause, wait, repeat)";
      });
    if (raw.too_many_options)
      return error(Code::limit, options[3].name.pos, [&](Text& m) { m << a.text << " has too many options"; });
    Step s;
    s.action = static_cast<ActionKind>(k);
    s.pos = a.pos;
    Slot main_slot = Slot::speed;
    bool main_needed = true;
    bool takes_speed = false;  // the option speed=
    bool moves = true;         // the option stop=
    switch (s.action) {
      case ActionKind::run: main_slot = Slot::speed; main_needed = false; break;
      case ActionKind::drive: main_slot = Slot::distance; takes_speed = true; break;
      case ActionKind::turn: main_slot = Slot::angle; takes_speed = true; break;
      case ActionKind::stop: main_slot = Slot::stop_mode; main_needed = false; moves = false; break;
      case ActionKind::pause: case ActionKind::wait: main_slot = Slot::duration; moves = false; break;
      case ActionKind::repeat: break;
    }
    const Number brake{static_cast<std::int32_t>(StopAction::brake), Unit::none, Dim::stop_mode};
    if (has_main) {
      if (!make_arg(main, main_slot, a.text, s.main)) return false;
    } else if (main_needed) {
      return error(Code::meaning, a.pos, [&](Text& m) { m << a.text << " needs " << describe(main_slot); });
    } else if (s.action == ActionKind::stop) {
      s.main = implicit_arg(brake, a.pos);
    }
    for (std::size_t i = 0; i < option_count; ++i) {
      const Option& o = options[i];
      const bool speed = takes_speed && o.name.text == "speed";
      if (!speed && !(moves && o.name.text == "stop"))
        return error(Code::meaning, o.name.pos, [&](Text& m) {
          m << a.text << " has no option '" << o.name.text << "'";
          if (takes_speed) m << " (its options: speed, stop)";
          else if (moves) m << " (its option: stop)";
          else m << " (it takes no options)";
        });
      Arg& into = speed ? s.speed : s.halt;
      if (into.kind != Arg::Kind::none)
        return error(Code::meaning, o.name.pos, [&](Text& m) { m << o.name.text << " is given twice"; });
      if (!make_arg(o.value, speed ? Slot::speed : Slot::stop_mode, speed ? "speed=" : "stop=", into)) return false;
    }
    if (moves && s.halt.kind == Arg::Kind::none) {
      s.halt = implicit_arg(brake, a.pos);
    }
    // The speed of run, drive and turn defaults to the param `speed`.
    Arg* speed = s.action == ActionKind::run ? &s.main : takes_speed ? &s.speed : nullptr;
    if (speed != nullptr && speed->kind == Arg::Kind::none) {
      const std::uint8_t p = def.find_param("speed");
      if (p == kNone || def.params[p].dim() != Dim::plain)
        return error(Code::meaning, a.pos, [&](Text& m) {
          m << a.text << " needs a speed: write " << (s.action == ActionKind::run ? "run N" : "speed=N")
            << " or declare param speed";
        });
      speed->kind = Arg::Kind::param;
      speed->param = p;
      speed->pos = a.pos;
      speed->implicit = true;
    }
    if (def.step_count >= kMaxSteps)
      return error(Code::limit, a.pos, [&](Text& m) { m << "too many actions (at most " << kMaxSteps << ")"; });
    def.steps[def.step_count++] = s;
    return true;
  }

  bool commit_repeat() noexcept {
    Number n;
    if (!number(repeat_count, Unit::none, n)) return false;
    if (n.dim != Dim::plain)
      return error(Code::meaning, repeat_count.pos, [&](Text& m) {
        m << "repeat takes " << describe(Slot::count) << ", not '" << repeat_count.text << "'";
      });
    if (n.value < 1 || n.value > kMaxRepeat)
      return error(Code::range, repeat_count.pos, [&](Text& m) {
        m << "repeat count " << n.value << " is outside 1.." << kMaxRepeat;
      });
    if (too_many_steps)
      return error(Code::limit, repeat_count.pos, [&](Text& m) {
        m << "too many actions in one repeat (at most " << kMaxRepeatSteps << ")";
      });
    for (std::uint8_t k = first_step; k < def.step_count; ++k)
      if (def.steps[k].action == ActionKind::run)
        return error(Code::meaning, def.steps[k].pos, [&](Text& m) { m << "run never finishes, so it cannot be inside repeat"; });
    repeat = static_cast<std::uint16_t>(n.value);
    return true;
  }

  bool commit_state() noexcept {
    const Tok& n = state_name;
    if (!name_fits(n)) return false;
    const std::uint8_t dup = def.find_state(n.text);
    if (dup != kNone)
      return error(Code::meaning, n.pos, [&](Text& m) {
        m << "state '" << n.text << "' is already defined at line " << def.states[dup].pos.line;
      });
    // Room for this state and for the implicit `end`.
    const bool is_end = n.text == "end";
    const std::size_t reserve = is_end || def.find_state("end") != kNone ? 0 : 1;
    if (def.state_count + reserve >= kMaxStates)
      return error(Code::limit, n.pos, [&](Text& m) {
        m << "too many states (at most " << kMaxStates << ", end included)";
      });
    first_step = def.step_count;
    repeat = 1;
    for (std::size_t k = 0; k < raw_step_count; ++k)
      if (!commit_step(raw_steps[k])) return false;
    if (has_repeat && !commit_repeat()) return false;
    const std::uint8_t steps = static_cast<std::uint8_t>(def.step_count - first_step);
    const Step& first = def.steps[first_step];
    if (is_end) {
      if (def.state_count == 0)
        return error(Code::meaning, n.pos, [&](Text& m) {
          m << "the first state is where the behaviour starts: it cannot be the stop state end";
        });
      if (repeat != 1 || steps != 1 || first.action != ActionKind::stop)
        return error(Code::meaning, first.pos, [&](Text& m) {
          m << "the stop state end can only stop the motors (stop coast, brake or hold)";
        });
      if (has_next)
        return error(Code::meaning, next_name.pos, [&](Text& m) { m << "the stop state end has no next state"; });
    } else {
      const bool unbounded = repeat == 1 && steps == 1 && first.action == ActionKind::run;
      if (unbounded && has_next)
        return error(Code::meaning, next_name.pos, [&](Text& m) {
          m << "run never finishes, so state " << n.text << " has no default next state (leave it with on or when)";
        });
      if (!unbounded && !has_next)
        return error(Code::meaning, n.pos, [&](Text& m) {
          m << "state " << n.text << " needs a default next state (-> NAME): its action finishes";
        });
    }
    State& st = def.states[def.state_count];
    st = State{};
    st.name.set(n.text);
    st.pos = n.pos;
    st.repeat = repeat;
    st.first_step = first_step;
    st.step_count = steps;
    st.first_reaction = def.reaction_count;
    if (has_next) {
      st.next_pos = next_name.pos;
      add_ref(&st.next, next_name);
    }
    if (def.state_count == 0) def.global_reactions = def.reaction_count;
    current = def.state_count++;
    return true;
  }

  bool reaction_owner(Pos p, std::uint8_t& owner) noexcept {
    owner = current;
    if (current != kEveryState && def.states[current].name.view() == "end")
      return error(Code::meaning, p, [&](Text& m) { m << "the stop state end has no reactions"; });
    return true;
  }

  bool add_reaction(const Reaction& r) noexcept {
    if (def.reaction_count >= kMaxReactions)
      return error(Code::limit, r.pos, [&](Text& m) { m << "too many reactions (at most " << kMaxReactions << ")"; });
    def.reactions[def.reaction_count] = r;
    if (!target_ignore) add_ref(&def.reactions[def.reaction_count].target, target_name);
    ++def.reaction_count;
    if (current != kEveryState) ++def.states[current].reaction_count;
    return true;
  }

  /// An earlier reaction of the same owner to the same event, or nullptr.
  const Reaction* same_event(std::uint8_t owner, EventKind e) const noexcept {
    const std::uint8_t from = owner == kEveryState ? 0 : def.states[owner].first_reaction;
    for (std::uint8_t k = from; k < def.reaction_count; ++k) {
      const Reaction& r = def.reactions[k];
      if (r.trigger == Trigger::event && r.event == e) return &r;
    }
    return nullptr;
  }

  bool commit_on() noexcept {
    std::uint8_t owner = kEveryState;
    if (!reaction_owner(events[0].pos, owner)) return false;
    for (std::size_t k = 0; k < event_count; ++k) {
      const Tok& t = events[k];
      if (k >= kMaxReactions)
        return error(Code::limit, t.pos, [&](Text& m) { m << "too many reactions (at most " << kMaxReactions << ")"; });
      std::uint8_t e = 0;
      while (e < robot::kEventKindCount && to_string(static_cast<EventKind>(e)) != t.text) ++e;
      if (e == robot::kEventKindCount)
        return error(Code::meaning, t.pos, [&](Text& m) {
          m << "unknown event '" << t.text
            << "' (events: OBSTACLE_DETECTED, PROXIMITY_ALERT, DEVICE_CONNECTED, DEVICE_ERROR)";
        });
      const EventKind ev = static_cast<EventKind>(e);
      if (severity_of(ev) == robot::Severity::critical)
        return error(Code::meaning, t.pos, [&](Text& m) {
          m << t.text << " is critical: the lifecycle handles it (the behaviour stops), a behaviour cannot react to it";
        });
      if (const Reaction* r = same_event(owner, ev))
        return error(Code::meaning, t.pos, [&](Text& m) {
          if (owner == kEveryState) m << t.text << " already has a behaviour-wide reaction (line " << r->pos.line << ")";
          else m << "state " << def.states[owner].name.view() << " already reacts to " << t.text << " (line " << r->pos.line << ")";
        });
      Reaction r;
      r.owner = owner;
      r.trigger = Trigger::event;
      r.event = ev;
      r.pos = t.pos;
      r.target = kIgnore;
      r.target_pos = target_name.pos;
      if (!add_reaction(r)) return false;
    }
    return true;
  }

  bool commit_when() noexcept {
    std::uint8_t owner = kEveryState;
    if (!reaction_owner(sensor_name.pos, owner)) return false;
    const Tok& t = sensor_name;
    std::uint8_t s = 0;
    while (s < kSensorCount && to_string(static_cast<Sensor>(s)) != t.text) ++s;
    if (s == kSensorCount)
      return error(Code::meaning, t.pos, [&](Text& m) {
        m << "unknown sensor '" << t.text << "' (sensors: distance, touch, colour, gyro)";
      });
    Reaction r;
    r.owner = owner;
    r.trigger = Trigger::condition;
    r.sensor = static_cast<Sensor>(s);
    r.pos = t.pos;
    for (std::uint8_t o = 0; o <= static_cast<std::uint8_t>(Op::ne); ++o)
      if (to_string(static_cast<Op>(o)) == op.text) r.op = static_cast<Op>(o);
    const Slot slot = r.sensor == Sensor::distance ? Slot::distance
                      : r.sensor == Sensor::touch  ? Slot::touch
                      : r.sensor == Sensor::colour ? Slot::colour
                                                   : Slot::angle;
    char who[24];
    Text w(who, sizeof who);
    w << "when " << t.text;
    if (!make_arg(last_arg, slot, w.view(), r.value)) return false;
    if (r.value.kind == Arg::Kind::param && def.params[r.value.param].random)
      return error(Code::meaning, r.value.pos, [&](Text& m) {
        m << "a condition compares with a fixed value, not the random param $" << def.params[r.value.param].name.view();
      });
    if ((r.sensor == Sensor::colour || r.sensor == Sensor::touch) && r.op != Op::eq && r.op != Op::ne)
      return error(Code::meaning, t.pos, [&](Text& m) { m << t.text << " is compared with = or !="; });
    if (target_ignore)
      return error(Code::meaning, target_name.pos, [&](Text& m) {
        m << "a condition needs a state to go to (ignore is for events)";
      });
    r.target = kIgnore;
    r.target_pos = target_name.pos;
    return add_reaction(r);
  }

  bool commit_header() noexcept {
    const Tok& n = behaviour_name;
    if (have_header)
      return error(Code::meaning, n.pos, [&](Text& m) {
        m << "behaviour is written twice (first at line " << def.name_pos.line << ")";
      });
    if (!name_fits(n)) return false;
    have_header = true;
    def.name.set(n.text);
    def.name_pos = n.pos;
    return true;
  }

  /// Interprets the statement just read (its end is reached).
  bool commit() noexcept {
    const Stmt s = stmt;
    stmt = Stmt::none;
    switch (s) {
      case Stmt::none: return true;
      case Stmt::behaviour: return commit_header();
      case Stmt::param: return commit_param();
      case Stmt::report: return commit_report();
      case Stmt::state: return commit_state();
      case Stmt::on: return commit_on();
      case Stmt::when: return commit_when();
    }
    return true;
  }

  bool resolve() noexcept {
    if (!have_header)
      return error(Code::meaning, Pos{1, 1}, [&](Text& m) { m << "a definition starts with 'behaviour NAME'"; });
    if (def.state_count == 0)
      return error(Code::meaning, def.name_pos, [&](Text& m) {
        m << "behaviour " << def.name.view() << " has no state (write one: state NAME = ACTION -> NEXT)";
      });
    std::uint8_t end = def.find_state("end");
    if (end == kNone) {  // the predefined stop state: stop brake
      Step s;
      s.action = ActionKind::stop;
      s.main = implicit_arg(Number{static_cast<std::int32_t>(StopAction::brake), Unit::none, Dim::stop_mode}, Pos{});
      if (def.step_count >= kMaxSteps)
        return error(Code::limit, def.name_pos, [&](Text& m) { m << "too many actions (at most " << kMaxSteps << ", the stop state's included)"; });
      State& st = def.states[def.state_count];
      st = State{};
      st.name.set("end");
      st.first_step = def.step_count;
      st.step_count = 1;
      st.first_reaction = def.reaction_count;
      st.implicit = true;
      def.steps[def.step_count++] = s;
      end = def.state_count++;
    }
    def.stop = end;
    def.start = 0;
    for (std::size_t k = 0; k < ref_count; ++k) {
      const std::uint8_t i = def.find_state(refs[k].name.text);
      if (i == kNone)
        return error(Code::meaning, refs[k].name.pos, [&](Text& m) { m << "unknown state '" << refs[k].name.text << "'"; });
      *refs[k].slot = i;
    }
    return true;
  }

  /// Writes the syntax error found at the furthest failure.
  void syntax_error() noexcept {
    failed = true;
    MessageWriter w(diag, Code::syntax, far_pos);
    Text& m = w.text();
    m << "expected ";
    std::size_t n = 0;
    for (std::size_t e = 1; e < grammar::kExpectCount; ++e)
      if (far_set & (std::uint32_t{1} << e)) ++n;
    std::size_t k = 0;
    for (std::size_t e = 1; e < grammar::kExpectCount; ++e) {
      if (!(far_set & (std::uint32_t{1} << e))) continue;
      if (k > 0) m << (k + 1 == n ? " or " : ", ");
      m << grammar::to_text(static_cast<grammar::Expect>(e));
      ++k;
    }
    m << ", found ";
    found(m, far_off);
  }

  /// What is at @p off, for "found ...".
  void found(Text& m, std::size_t off) const noexcept {
    if (off >= src.size()) {
      m << "the end of the definition";
      return;
    }
    const auto c = static_cast<unsigned char>(src[off]);
    if (c == '\n' || (c == '\r' && off + 1 < src.size() && src[off + 1] == '\n')) {
      m << "the end of the line";
      return;
    }
    auto idc = [](unsigned char x) {
      return (x >= 'a' && x <= 'z') || (x >= 'A' && x <= 'Z') || (x >= '0' && x <= '9') || x == '_' || x == '.';
    };
    if (idc(c)) {
      std::size_t e = off;
      while (e < src.size() && e - off < 32 && idc(static_cast<unsigned char>(src[e]))) ++e;
      const std::string_view w = src.substr(off, e - off);
      m << "'" << w << "'";
      for (std::string_view kw : {"behaviour", "param", "report", "every", "state", "repeat", "on", "when", "random", "ignore"})
        if (w == kw) m << " (a keyword)";
      return;
    }
    if (c == ' ' || c == '\t') {
      m << (c == ' ' ? "a space" : "a tab");
      return;
    }
    if (c > 0x20 && c < 0x7F) {
      m << "'" << static_cast<char>(c) << "'";
      return;
    }
    const char* hex = "0123456789ABCDEF";
    m << "byte 0x" << hex[c >> 4] << hex[c & 15];
  }
};

// ---- PEGTL actions: tokens into registers, constructs committed -----------------------------------

template <typename Rule>
struct Act : grammar::pegtl::nothing<Rule> {};

template <typename In>
Tok tok(const In& in) noexcept {
  const auto it = in.iterator();
  return Tok{in.string_view(), Parser::pos_of(it.line, it.column)};
}

#define EV3_BHV_REGISTER(rule, field)                                   \
  template <>                                                           \
  struct Act<grammar::rule> {                                           \
    template <typename In>                                              \
    static void apply(const In& in, Parser& p) noexcept { p.field = tok(in); } \
  }
EV3_BHV_REGISTER(behaviour_name, behaviour_name);
EV3_BHV_REGISTER(param_name, param_name);
EV3_BHV_REGISTER(range_lo, range_lo);
EV3_BHV_REGISTER(range_hi, range_hi);
EV3_BHV_REGISTER(state_name, state_name);
EV3_BHV_REGISTER(target_name, target_name);
EV3_BHV_REGISTER(sensor_name, sensor_name);
EV3_BHV_REGISTER(op, op);
EV3_BHV_REGISTER(repeat_count, repeat_count);
#undef EV3_BHV_REGISTER

template <>
struct Act<grammar::number> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    p.last_arg = RawArg{RawArg::Kind::number, false, tok(in)};
  }
};
template <>
struct Act<grammar::word_value> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    p.last_arg = RawArg{RawArg::Kind::word, false, tok(in)};
  }
};
template <>
struct Act<grammar::param_ref> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    Tok t = tok(in);  // its place is the '$' (or the '-'), its text the name
    const bool neg = t.text.front() == '-';
    t.text.remove_prefix(neg ? 2 : 1);
    p.last_arg = RawArg{RawArg::Kind::param, neg, t};
  }
};

template <>
struct Act<grammar::unknown_word> {
  template <typename In>
  static bool apply(const In& in, Parser& p) noexcept {
    const Tok t = tok(in);
    return p.error(Code::meaning, t.pos, [&](Text& m) {
      m << "unknown statement '" << t.text << "' (statements: behaviour, param, report, state, on, when)";
    });
  }
};

template <>
struct Act<grammar::statement_end> {
  template <typename In>
  static bool apply(const In&, Parser& p) noexcept { return p.commit(); }
};

// Statement keywords: the header comes first; each resets its registers.
template <>
struct Act<grammar::kw_behaviour> {
  template <typename In>
  static void apply(const In&, Parser& p) noexcept { p.stmt = Parser::Stmt::behaviour; }
};
template <>
struct Act<grammar::kw_param> {
  template <typename In>
  static bool apply(const In& in, Parser& p) noexcept {
    p.stmt = Parser::Stmt::param;
    p.param_random = false;
    return p.header_first(tok(in).pos);
  }
};
template <>
struct Act<grammar::random_value> {
  template <typename In>
  static void apply(const In&, Parser& p) noexcept { p.param_random = true; }
};

template <>
struct Act<grammar::kw_report> {
  template <typename In>
  static bool apply(const In& in, Parser& p) noexcept {
    p.stmt = Parser::Stmt::report;
    p.report_count = 0;
    p.has_period = false;
    return p.header_first(tok(in).pos);
  }
};
template <>
struct Act<grammar::report_sensor> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    if (p.report_count <= kMaxReports) p.report_sensors[p.report_count++] = tok(in);
  }
};
template <>
struct Act<grammar::report_period> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    p.report_period = tok(in);
    p.has_period = true;
  }
};

template <>
struct Act<grammar::kw_state> {
  template <typename In>
  static bool apply(const In& in, Parser& p) noexcept {
    p.stmt = Parser::Stmt::state;
    p.raw_step_count = 0;
    p.too_many_steps = false;
    p.has_repeat = false;
    p.has_next = false;
    return p.header_first(tok(in).pos);
  }
};
template <>
struct Act<grammar::action_name> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    p.step = Parser::RawStep{};
    p.step.action = tok(in);
  }
};
template <>
struct Act<grammar::main_arg> {
  template <typename In>
  static void apply(const In&, Parser& p) noexcept {
    p.step.main = p.last_arg;
    p.step.has_main = true;
  }
};
template <>
struct Act<grammar::option_name> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    if (p.step.option_count < 4) p.step.options[p.step.option_count].name = tok(in);
  }
};
template <>
struct Act<grammar::option> {
  template <typename In>
  static void apply(const In&, Parser& p) noexcept {
    if (p.step.option_count < 4) p.step.options[p.step.option_count++].value = p.last_arg;
    else p.step.too_many_options = true;
  }
};
template <>
struct Act<grammar::step> {
  template <typename In>
  static void apply(const In&, Parser& p) noexcept {
    if (p.raw_step_count <= kMaxRepeatSteps) p.raw_steps[p.raw_step_count++] = p.step;
    else p.too_many_steps = true;
  }
};
template <>
struct Act<grammar::repeat_action> {
  template <typename In>
  static void apply(const In&, Parser& p) noexcept {
    p.has_repeat = true;
    if (p.raw_step_count > kMaxRepeatSteps) p.too_many_steps = true;
  }
};
template <>
struct Act<grammar::next_name> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    p.next_name = tok(in);
    p.has_next = true;
  }
};

template <>
struct Act<grammar::kw_on> {
  template <typename In>
  static bool apply(const In& in, Parser& p) noexcept {
    p.stmt = Parser::Stmt::on;
    p.event_count = 0;
    p.target_ignore = false;
    return p.header_first(tok(in).pos);
  }
};
template <>
struct Act<grammar::event_name> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    if (p.event_count <= kMaxReactions) p.events[p.event_count++] = tok(in);
  }
};
template <>
struct Act<grammar::kw_ignore> {
  template <typename In>
  static void apply(const In& in, Parser& p) noexcept {
    p.target_ignore = true;
    p.target_name = tok(in);
  }
};

template <>
struct Act<grammar::kw_when> {
  template <typename In>
  static bool apply(const In& in, Parser& p) noexcept {
    p.stmt = Parser::Stmt::when;
    p.target_ignore = false;
    return p.header_first(tok(in).pos);
  }
};

// ---- Control: the furthest failure of a named rule --------------------------------------------------

template <typename Rule>
struct Ctl : grammar::pegtl::normal<Rule> {
  static constexpr grammar::Expect kExpect = grammar::expect<Rule>::value;

  template <typename In>
  static void start(const In& in, Parser& p) noexcept {
    if constexpr (kExpect != grammar::Expect::none) {
      const auto it = in.iterator();
      p.push(it.byte, Parser::pos_of(it.line, it.column));
    }
  }
  template <typename In>
  static void success(const In&, Parser& p) noexcept {
    if constexpr (kExpect != grammar::Expect::none) p.pop();
  }
  template <typename In>
  static void failure(const In&, Parser& p) noexcept {
    if constexpr (kExpect != grammar::Expect::none) p.fail_at(kExpect);
  }
};

}  // namespace detail

/// Parses the text of a behaviour into @p def. Returns true on success; otherwise @p diag holds the
/// first error (a syntax error at the furthest place the text still followed the grammar, or the
/// first meaning error in reading order) and @p def is unspecified. At most kMaxSource bytes.
inline bool parse(std::string_view text, Definition& def, Diagnostic& diag) noexcept {
  def = Definition{};
  diag = Diagnostic{};
  if (text.size() > kMaxSource) {
    MessageWriter w(diag, Code::limit, Pos{});
    w.text() << "the definition is " << text.size() << " bytes, more than " << kMaxSource;
    return false;
  }
  detail::Parser p(text, def, diag);
  grammar::pegtl::memory_input<grammar::pegtl::tracking_mode::eager, grammar::pegtl::eol::lf_crlf, const char*> in(
      text.data(), text.size(), "behaviour");
  const bool ok = grammar::pegtl::parse<grammar::definition, detail::Act, detail::Ctl>(in, p);
  if (p.failed) return false;
  if (!ok) {
    p.syntax_error();
    return false;
  }
  return p.resolve();
}

/// Applies BEHAVIOUR's arguments (`key=value` each) to the params of @p def: a number without a unit
/// takes the unit of the param's default (`seconds=2` for `param seconds = 1s` is 2 s), a random
/// param takes `random LO..HI` or a fixed value, a fixed one a value of its own kind. Ranges are left
/// to check(). Returns false with the first error in @p diag (no line: "argument 'speed=x': ...").
inline bool apply_args(Definition& def, const std::string_view* args, std::size_t count, Diagnostic& diag) noexcept {
  for (std::size_t k = 0; k < count; ++k) {
    const std::string_view a = args[k];
    const std::size_t eq = a.find('=');
    auto fail = [&](auto&& write) {
      MessageWriter w(diag, Code::meaning, Pos{});
      w.text() << "argument '" << a << "': ";
      write(w.text());
      return false;
    };
    if (eq == std::string_view::npos || eq == 0) return fail([&](Text& m) { m << "expected key=value"; });
    const std::string_view key = a.substr(0, eq);
    std::string_view val = a.substr(eq + 1);
    const std::uint8_t i = def.find_param(key);
    if (i == kNone)
      return fail([&](Text& m) {
        m << "unknown param '" << key << "' (";
        if (def.param_count == 0) m << "behaviour " << def.name.view() << " has no params";
        for (std::uint8_t j = 0; j < def.param_count; ++j) m << (j ? ", " : "params: ") << def.params[j].name.view();
        m << ")";
      });
    Param& p = def.params[i];
    Param q = p;
    auto num = [&](std::string_view t, Number& out) {
      std::size_t unit_at = 0;
      const detail::NumError e = detail::parse_number(t, p.lo.unit, out, unit_at);
      return e == detail::NumError::ok && unit_at > 0 && (t[0] != '-' || unit_at > 1);
    };
    if (val.substr(0, 6) == "random") {
      std::string_view range = val.substr(6);
      while (!range.empty() && range.front() == ' ') range.remove_prefix(1);
      if (range.empty()) {
        if (!p.random) return fail([&](Text& m) { m << "random needs a range here: random LO..HI"; });
      } else {
        const std::size_t dots = range.find("..");
        Number lo, hi;
        if (dots == std::string_view::npos || !num(range.substr(0, dots), lo) || !num(range.substr(dots + 2), hi))
          return fail([&](Text& m) { m << "expected random LO..HI"; });
        q.random = true;
        q.lo = lo;
        q.hi = hi;
        if (q.lo.value > q.hi.value) return fail([&](Text& m) { m << "the random range is empty"; });
      }
    } else {
      Number n;
      if (!detail::word_value(val, n) && !num(val, n))
        return fail([&](Text& m) { m << "'" << val << "' is not a value"; });
      q.random = false;
      q.lo = n;
    }
    auto same = [&](Dim d) { return d == p.dim() || (d == Dim::plain && p.dim() == Dim::angle); };
    if (!same(q.lo.dim) || (q.random && !same(q.hi.dim)))
      return fail([&](Text& m) { m << key << " takes " << detail::describe(p.dim()) << ", not '" << val << "'"; });
    q.lo.dim = q.hi.dim = p.dim();
    // A unitless number of an angle param ("angle=45" over `random 90..270deg`) is written back with
    // its unit: a bare "45" would read back as a plain number (compact() must parse to the same tables).
    if (p.dim() == Dim::angle) {
      if (q.lo.unit == Unit::none) q.lo.unit = Unit::deg;
      if (q.random && q.hi.unit == Unit::none) q.hi.unit = Unit::deg;
    }
    if (key == "seed" && q.lo.value < 0) return fail([&](Text& m) { m << "seed is 0 or more"; });
    p = q;
  }
  return true;
}

}  // namespace ev3proto::behaviour
