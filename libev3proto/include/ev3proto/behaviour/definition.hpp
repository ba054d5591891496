/// @file behaviour/definition.hpp
/// @brief A parsed behaviour: the fixed-capacity tables the runtime executes (docs/behaviours.md).
///
/// parse() (parser.hpp) fills a Definition from the text of the language; check() (checker.hpp)
/// explores it. The runtime runs it directly: the current state's steps (repeat times), then its
/// default next state; an event selects the state's reaction (on_event()), a condition
/// (condition()) is tested every tick; a step's arguments are resolved with value(), which draws
/// `random` params from the behaviour's seeded Rng. No heap, no exceptions, no pointers into the
/// source text: a Definition is trivially copyable and self-contained.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>
#include <type_traits>

#include "../decimal.hpp"
#include "model.hpp"

namespace ev3proto::behaviour {

// ---- Limits (docs/behaviours.md "Limits") -----------------------------------------------------

inline constexpr std::size_t kMaxSource = 4096;   ///< bytes of a definition's text
inline constexpr std::size_t kMaxStates = 32;     ///< states, the stop state `end` included
inline constexpr std::size_t kMaxSteps = 64;      ///< actions in all states (a repeat's count each)
inline constexpr std::size_t kMaxRepeatSteps = 8; ///< actions inside one repeat
inline constexpr std::size_t kMaxReactions = 64;  ///< reactions: each event of an `on`, each `when`
inline constexpr std::size_t kMaxParams = 16;     ///< params
inline constexpr std::size_t kMaxReports = 4;     ///< sensors in `report`
inline constexpr std::size_t kMaxName = 24;       ///< characters of a name (behaviour, state, param)
inline constexpr std::size_t kMaxMessage = 384;   ///< characters of one diagnostic (longer is cut)
inline constexpr std::int32_t kMaxRepeat = 100;   ///< largest repeat count

/// "No state": a state without a default next state (its action never finishes by itself).
inline constexpr std::uint8_t kNone = 0xFF;
/// Reaction target `ignore`: the event is handled by doing nothing.
inline constexpr std::uint8_t kIgnore = 0xFE;
/// Owner of a behaviour-wide reaction (written before the first state): every state but `end`.
inline constexpr std::uint8_t kEveryState = 0xFD;

/// A place in the definition's text: 1-based line and column (columns count bytes).
struct Pos {
  std::uint16_t line = 0; ///< 0 for things the text does not contain (the implicit `end`)
  std::uint16_t col = 0;
};

/// A name of at most kMaxName characters, stored in place.
struct Name {
  char text[kMaxName + 1] = {};
  std::uint8_t len = 0;

  std::string_view view() const noexcept { return std::string_view(text, len); }
  /// Stores @p s; false (and nothing stored) when it is longer than kMaxName.
  bool set(std::string_view s) noexcept {
    if (s.size() > kMaxName) return false;
    std::memcpy(text, s.data(), s.size());
    text[s.size()] = '\0';
    len = static_cast<std::uint8_t>(s.size());
    return true;
  }
};

// ---- Values -------------------------------------------------------------------------------------

/// The unit a number was written with (kept so that the printer writes it back the same way).
enum class Unit : std::uint8_t { none, mm, cm, m, ms, s, deg };

/// How many base units one of @p u is (1 cm = 10 mm, 1 s = 1000 ms).
constexpr std::int32_t factor_of(Unit u) noexcept {
  return u == Unit::cm ? 10 : (u == Unit::m || u == Unit::s) ? 1000 : 1;
}

/// Base units: distances in mm, durations in ms, angles in degrees, speeds in degrees of the wheel
/// per second (a plain number). A colour or a stop mode is a word, stored as its code.
enum class Dim : std::uint8_t { plain, distance, duration, angle, colour, stop_mode };

/// A value in base units.
struct Number {
  std::int32_t value = 0;    ///< in base units (mm, ms, degrees, deg/s) or a word's code
  Unit unit = Unit::none;    ///< as written
  Dim dim = Dim::plain;
};

/// Colours of the colour sensor in COL-COLOR mode; the value is ev3dev's value0.
enum class Colour : std::uint8_t { none, black, blue, green, yellow, red, white, brown };

/// A sensor reading a condition tests or a report sends.
enum class Sensor : std::uint8_t {
  distance, ///< ultrasonic, US-DIST-CM, in mm
  touch,    ///< touch, TOUCH, 0 or 1
  colour,   ///< colour, COL-COLOR, a Colour
  gyro,     ///< gyro, GYRO-ANG, degrees
};
inline constexpr std::size_t kSensorCount = 4;

/// Comparison of a condition.
enum class Op : std::uint8_t { lt, le, gt, ge, eq, ne };

// ---- Tables -----------------------------------------------------------------------------------------

/// An action's argument: absent, a constant, or a param (maybe negated: `-$backoff`).
struct Arg {
  enum class Kind : std::uint8_t { none, constant, param };
  Kind kind = Kind::none;
  bool negate = false;      ///< `-$name`
  bool implicit = false;    ///< not written: a speed taken from the param `speed`, stop's brake
  std::uint8_t param = 0;   ///< index in Definition::params when kind == param
  Number num;               ///< the constant when kind == constant
  Pos pos;
};

/// One action of a state. Arguments by action: run (main = speed), drive (main = distance, speed),
/// turn (main = angle, speed), stop (main = stop mode), pause and wait (main = duration). `halt` is
/// how run, drive and turn stop the motors when they end or are interrupted (option stop=, brake
/// when not written).
struct Step {
  ActionKind action = ActionKind::pause;
  Arg main;
  Arg speed;
  Arg halt;
  Pos pos;
};

/// A state: its steps run `repeat` times, then `next` (kNone: the action never finishes).
struct State {
  Name name;
  Pos pos;
  std::uint16_t repeat = 1;      ///< 1 for a plain action; n for `repeat n (...)`
  std::uint8_t first_step = 0;   ///< into Definition::steps
  std::uint8_t step_count = 0;
  std::uint8_t next = kNone;     ///< default next state, or kNone
  Pos next_pos;
  std::uint8_t first_reaction = 0; ///< its own reactions, into Definition::reactions
  std::uint8_t reaction_count = 0;
  bool implicit = false;         ///< the predefined stop state `end` the text did not write
};

/// What leaves a state besides its default transition.
enum class Trigger : std::uint8_t { event, condition };

/// `on EVENT -> target` or `when SENSOR OP VALUE -> target`.
struct Reaction {
  std::uint8_t owner = kEveryState; ///< the state it belongs to, or kEveryState
  Trigger trigger = Trigger::event;
  EventKind event = EventKind::OBSTACLE_DETECTED; ///< trigger == event
  Sensor sensor = Sensor::distance;       ///< trigger == condition
  Op op = Op::lt;                         ///< trigger == condition
  Arg value;                              ///< trigger == condition: what the reading is compared with
  std::uint8_t target = kIgnore;          ///< a state, or kIgnore
  Pos pos;                                ///< of the event or the sensor
  Pos target_pos;
};

/// A param: a fixed value, or a random range drawn from each time it is used.
struct Param {
  Name name;
  Pos pos;
  bool random = false;
  Number lo;  ///< the value, or the range's low end
  Number hi;  ///< the range's high end (random only)
  Dim dim() const noexcept { return lo.dim; }
};

/// The sensors reported as SENSOR_VALUE and how often.
struct Report {
  Sensor sensors[kMaxReports] = {};
  std::uint8_t count = 0;
  Number period{1000, Unit::s, Dim::duration}; ///< default: one report per second
  Pos pos;
};

/// Smallest and largest report period (ms): at most 10 reports per sensor per second, at least one a
/// minute. Twenty robots reporting three sensors at the 1 s default send 60 small datagrams a second.
inline constexpr std::int32_t kMinReportPeriod = 100;
inline constexpr std::int32_t kMaxReportPeriod = 60000;

/// Deterministic random numbers for `random` params (xorshift32; seed 0 is taken as 1).
class Rng {
 public:
  explicit Rng(std::uint32_t seed = 1) noexcept : s_(seed == 0 ? 1u : seed) {}
  std::uint32_t next() noexcept {
    s_ ^= s_ << 13;
    s_ ^= s_ >> 17;
    s_ ^= s_ << 5;
    return s_;
  }
  /// A value in [lo, hi] (lo <= hi).
  std::int32_t uniform(std::int32_t lo, std::int32_t hi) noexcept {
    const std::uint32_t span = static_cast<std::uint32_t>(hi) - static_cast<std::uint32_t>(lo) + 1u;
    const std::uint32_t r = span == 0 ? next() : next() % span;
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(lo) + r);
  }

 private:
  std::uint32_t s_;
};

/// A parsed behaviour.
struct Definition {
  Name name;
  Pos name_pos;
  Param params[kMaxParams];
  std::uint8_t param_count = 0;
  State states[kMaxStates];
  std::uint8_t state_count = 0;
  std::uint8_t start = 0;           ///< the first state written
  std::uint8_t stop = kNone;        ///< the stop state `end`
  Step steps[kMaxSteps];
  std::uint8_t step_count = 0;
  Reaction reactions[kMaxReactions];
  std::uint8_t reaction_count = 0;
  std::uint8_t global_reactions = 0; ///< reactions[0 .. global_reactions) belong to every state
  Report report;

  /// Index of the state called @p n, or kNone.
  std::uint8_t find_state(std::string_view n) const noexcept {
    for (std::uint8_t i = 0; i < state_count; ++i)
      if (states[i].name.view() == n) return i;
    return kNone;
  }
  /// Index of the param called @p n, or kNone.
  std::uint8_t find_param(std::string_view n) const noexcept {
    for (std::uint8_t i = 0; i < param_count; ++i)
      if (params[i].name.view() == n) return i;
    return kNone;
  }

  /// The reaction of state @p s to event @p e: its own, else the behaviour-wide one, else nullptr
  /// (the event is ignored). A reaction whose target is kIgnore handles the event by doing nothing.
  const Reaction* on_event(std::uint8_t s, EventKind e) const noexcept {
    if (s >= state_count || s == stop) return nullptr;
    const State& st = states[s];
    for (std::uint8_t k = 0; k < st.reaction_count; ++k) {
      const Reaction& r = reactions[st.first_reaction + k];
      if (r.trigger == Trigger::event && r.event == e) return &r;
    }
    for (std::uint8_t k = 0; k < global_reactions; ++k) {
      const Reaction& r = reactions[k];
      if (r.trigger == Trigger::event && r.event == e) return &r;
    }
    return nullptr;
  }

  /// The @p k-th condition tested in state @p s (its own `when`s in order, then the behaviour-wide
  /// ones), or nullptr past the last. The runtime takes the first that holds each tick.
  const Reaction* condition(std::uint8_t s, std::size_t k) const noexcept {
    if (s >= state_count || s == stop) return nullptr;
    const State& st = states[s];
    for (std::uint8_t i = 0; i < st.reaction_count; ++i) {
      const Reaction& r = reactions[st.first_reaction + i];
      if (r.trigger == Trigger::condition && k-- == 0) return &r;
    }
    for (std::uint8_t i = 0; i < global_reactions; ++i) {
      const Reaction& r = reactions[i];
      if (r.trigger == Trigger::condition && k-- == 0) return &r;
    }
    return nullptr;
  }

  /// The seed of the random params: the param `seed`, else 1.
  std::uint32_t seed() const noexcept {
    const std::uint8_t i = find_param("seed");
    return i == kNone ? 1u : static_cast<std::uint32_t>(params[i].lo.value);
  }

  /// The value of an argument in base units (a word's code for colours and stop modes): the constant,
  /// or the param's value, a random param drawing from @p rng. 0 for an absent argument.
  std::int32_t value(const Arg& a, Rng& rng) const noexcept {
    std::int32_t v = 0;
    if (a.kind == Arg::Kind::constant) {
      v = a.num.value;
    } else if (a.kind == Arg::Kind::param && a.param < param_count) {
      const Param& p = params[a.param];
      v = p.random ? rng.uniform(p.lo.value, p.hi.value) : p.lo.value;
    }
    return a.negate ? -v : v;
  }

  /// Whether condition @p r holds for a reading @p reading (base units, or the colour's code).
  bool holds(const Reaction& r, std::int32_t reading) const noexcept {
    Rng unused;
    const std::int32_t v = value(r.value, unused);  // conditions never use random params
    switch (r.op) {
      case Op::lt: return reading < v;
      case Op::le: return reading <= v;
      case Op::gt: return reading > v;
      case Op::ge: return reading >= v;
      case Op::eq: return reading == v;
      case Op::ne: return reading != v;
    }
    return false;
  }

  /// True when the state's action moves the robot (run, drive or turn among its steps). The events a
  /// moving state reacts to (a state, not ignore) are the ones that interrupt its action.
  bool moves(std::uint8_t s) const noexcept {
    const State& st = states[s];
    for (std::uint8_t k = 0; k < st.step_count; ++k) {
      const ActionKind a = steps[st.first_step + k].action;
      if (a == ActionKind::run || a == ActionKind::drive || a == ActionKind::turn) return true;
    }
    return false;
  }
};

static_assert(std::is_trivially_copyable<Definition>::value, "Definition must stay trivially copyable");

// ---- Diagnostics ------------------------------------------------------------------------------------

/// What a diagnostic is about. The last five are the checker's automaton rules; model_action and
/// robot_device become NOT reasons naming the action or device (thesis 6.1.2).
enum class Code : std::uint8_t {
  syntax,        ///< the text does not follow the grammar
  meaning,       ///< unknown name, wrong kind of value, duplicate, misplaced construct
  limit,         ///< a table of the language is full, a name or a number too long
  range,         ///< a value outside the model's or the language's limits
  model_action,  ///< an action the model lacks
  robot_device,  ///< a device the robot lacks
  unreachable,   ///< a state no path from the start reaches
  unguarded,     ///< a moving state without a reaction to OBSTACLE_DETECTED or PROXIMITY_ALERT
  no_return,     ///< a reaction that never returns to the normal course
  no_stop,       ///< a state with no way to the stop state
};

/// One error: where, what kind, and the message (without the "line L col C: " prefix).
struct Diagnostic {
  Code code = Code::syntax;
  Pos pos;
  char text[kMaxMessage + 1] = {};
  std::uint16_t len = 0;

  std::string_view message() const noexcept { return std::string_view(text, len); }
};

/// Appends text to a fixed buffer, cutting (and remembering it) when full.
class Text {
 public:
  Text(char* buf, std::size_t cap) noexcept : buf_(buf), cap_(cap) {}
  Text& operator<<(std::string_view s) noexcept {
    for (char c : s) put(c);
    return *this;
  }
  Text& operator<<(char c) noexcept {
    put(c);
    return *this;
  }
  template <typename T, typename = std::enable_if_t<std::is_integral<T>::value && !std::is_same<T, char>::value &&
                                                    !std::is_same<T, bool>::value>>
  Text& operator<<(T value) noexcept {
    char tmp[kMaxIntText];
    const char* e = write_int(tmp, static_cast<std::int64_t>(value));
    return *this << std::string_view(tmp, static_cast<std::size_t>(e - tmp));
  }
  std::size_t size() const noexcept { return len_; }
  bool overflow() const noexcept { return overflow_; }
  std::string_view view() const noexcept { return std::string_view(buf_, len_); }

 private:
  void put(char c) noexcept {
    if (len_ < cap_) buf_[len_++] = c;
    else overflow_ = true;
  }
  char* buf_;
  std::size_t cap_;
  std::size_t len_ = 0;
  bool overflow_ = false;
};

/// Starts a diagnostic's message; write into the returned Text, then call finish().
class MessageWriter {
 public:
  MessageWriter(Diagnostic& d, Code code, Pos pos) noexcept : d_(d), t_(d.text, kMaxMessage) {
    d.code = code;
    d.pos = pos;
  }
  Text& text() noexcept { return t_; }
  ~MessageWriter() {
    std::size_t n = t_.size();
    if (t_.overflow()) {  // mark the cut
      n = kMaxMessage;
      d_.text[n - 3] = d_.text[n - 2] = d_.text[n - 1] = '.';
    }
    d_.text[n] = '\0';
    d_.len = static_cast<std::uint16_t>(n);
  }

 private:
  Diagnostic& d_;
  Text t_;
};

/// Writes "line L col C: message" (the form NOT reasons and the tools use).
inline void write(Text& out, const Diagnostic& d) {
  if (d.pos.line != 0) out << "line " << std::int32_t{d.pos.line} << " col " << std::int32_t{d.pos.col} << ": ";
  out << d.message();
}

// ---- Names of the language's words --------------------------------------------------------------

constexpr std::string_view to_string(Sensor s) noexcept {
  switch (s) {
    case Sensor::distance: return "distance";
    case Sensor::touch: return "touch";
    case Sensor::colour: return "colour";
    case Sensor::gyro: return "gyro";
  }
  return "?";
}
constexpr std::string_view to_string(Op o) noexcept {
  switch (o) {
    case Op::lt: return "<";
    case Op::le: return "<=";
    case Op::gt: return ">";
    case Op::ge: return ">=";
    case Op::eq: return "=";
    case Op::ne: return "!=";
  }
  return "?";
}
constexpr std::string_view to_string(Unit u) noexcept {
  switch (u) {
    case Unit::none: return "";
    case Unit::mm: return "mm";
    case Unit::cm: return "cm";
    case Unit::m: return "m";
    case Unit::ms: return "ms";
    case Unit::s: return "s";
    case Unit::deg: return "deg";
  }
  return "";
}
constexpr std::string_view to_string(Colour c) noexcept {
  switch (c) {
    case Colour::none: return "none";
    case Colour::black: return "black";
    case Colour::blue: return "blue";
    case Colour::green: return "green";
    case Colour::yellow: return "yellow";
    case Colour::red: return "red";
    case Colour::white: return "white";
    case Colour::brown: return "brown";
  }
  return "?";
}

/// The device a sensor reading comes from.
constexpr Role device_of(Sensor s) noexcept {
  switch (s) {
    case Sensor::distance: return Role::ultrasonic;
    case Sensor::touch: return Role::touch;
    case Sensor::colour: return Role::colour;
    case Sensor::gyro: return Role::gyro;
  }
  return Role::gyro;
}

/// The ev3dev mode a sensor reading is taken in (SENSOR_VALUE's mode param).
constexpr std::string_view mode_of(Sensor s) noexcept {
  switch (s) {
    case Sensor::distance: return "US-DIST-CM";
    case Sensor::touch: return "TOUCH";
    case Sensor::colour: return "COL-COLOR";
    case Sensor::gyro: return "GYRO-ANG";
  }
  return "?";
}

}  // namespace ev3proto::behaviour
