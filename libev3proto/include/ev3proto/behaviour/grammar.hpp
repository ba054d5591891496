/// @file behaviour/grammar.hpp
/// @brief The behaviour language's grammar as PEGTL rules (docs/behaviours.md gives it as EBNF).
///
/// Header-only PEGTL (Debian tao-pegtl-dev) with no exceptions: no must<> and no raise; a syntax
/// error is found as the furthest point any rule with an Expect name failed at (parser.hpp).
/// Rules that carry a meaning get their own type (state_name, next_name, ...) so the parser's actions
/// know what each name is. Every rule here only recognises; the actions in parser.hpp interpret.
#pragma once

#include <tao/pegtl.hpp>

namespace ev3proto::behaviour::grammar {

namespace pegtl = tao::pegtl;

// ---- Lexical --------------------------------------------------------------------------------------
struct blank : pegtl::one<' ', '\t'> {};
struct sp : pegtl::star<blank> {};
struct comment : pegtl::seq<pegtl::one<'#'>, pegtl::star<pegtl::not_one<'\n', '\r'>>> {};
struct sep : pegtl::sor<pegtl::one<';'>, pegtl::eol> {};  // ';', "\n" or "\r\n"
struct end_of_text : pegtl::eof {};

struct letter : pegtl::ranges<'a', 'z', 'A', 'Z'> {};
struct idchar : pegtl::ranges<'a', 'z', 'A', 'Z', '0', '9', '_'> {};
struct word : pegtl::seq<letter, pegtl::star<idchar>> {};

struct kw_behaviour : TAO_PEGTL_KEYWORD("behaviour") {};
struct kw_param : TAO_PEGTL_KEYWORD("param") {};
struct kw_report : TAO_PEGTL_KEYWORD("report") {};
struct kw_every : TAO_PEGTL_KEYWORD("every") {};
struct kw_state : TAO_PEGTL_KEYWORD("state") {};
struct kw_repeat : TAO_PEGTL_KEYWORD("repeat") {};
struct kw_on : TAO_PEGTL_KEYWORD("on") {};
struct kw_when : TAO_PEGTL_KEYWORD("when") {};
struct kw_random : TAO_PEGTL_KEYWORD("random") {};
struct kw_ignore : TAO_PEGTL_KEYWORD("ignore") {};
struct keyword : pegtl::sor<kw_behaviour, kw_param, kw_report, kw_every, kw_state, kw_repeat, kw_on, kw_when,
                            kw_random, kw_ignore> {};
struct name : pegtl::seq<pegtl::not_at<keyword>, word> {};

struct eq : pegtl::one<'='> {};
struct eq_ahead : pegtl::one<'='> {};  // lookahead only: no expectation recorded
struct arrow : pegtl::string<'-', '>'> {};
struct comma : pegtl::one<','> {};
struct dotdot : pegtl::two<'.'> {};
struct lparen : pegtl::one<'('> {};
struct rparen : pegtl::one<')'> {};
struct list_sep : pegtl::seq<sp, comma, sp> {};

// A number: sign, digits, up to a fraction, then a unit glued to it (200ms, -10cm, 1.5s, 90).
struct number : pegtl::seq<pegtl::opt<pegtl::one<'-'>>, pegtl::plus<pegtl::digit>,
                           pegtl::opt<pegtl::one<'.'>, pegtl::plus<pegtl::digit>>, pegtl::star<letter>> {};

// ---- Values ---------------------------------------------------------------------------------------
struct ref_name : name {};
struct param_ref : pegtl::seq<pegtl::opt<pegtl::one<'-'>>, pegtl::one<'$'>, ref_name> {};
struct word_value : name {};
struct arg : pegtl::sor<number, param_ref, word_value> {};

// ---- Statements -----------------------------------------------------------------------------------
struct behaviour_name : name {};
struct behaviour_stmt : pegtl::seq<kw_behaviour, sp, behaviour_name> {};

struct param_name : name {};
struct range_lo : number {};
struct range_hi : number {};
struct random_value : pegtl::seq<kw_random, sp, range_lo, sp, dotdot, sp, range_hi> {};
struct fixed_value : pegtl::sor<number, word_value> {};
struct param_value : pegtl::sor<random_value, fixed_value> {};
struct param_stmt : pegtl::seq<kw_param, sp, param_name, sp, eq, sp, param_value> {};

struct report_sensor : name {};
struct report_period : number {};
struct every : TAO_PEGTL_KEYWORD("every") {};  // kw_every without the keyword lookahead's failures
struct report_stmt : pegtl::seq<kw_report, sp, pegtl::list<report_sensor, list_sep>,
                                pegtl::opt<sp, every, sp, report_period>> {};

struct action_name : name {};
struct main_arg : pegtl::seq<arg, pegtl::not_at<sp, eq_ahead>> {};
struct option_name : name {};
struct option : pegtl::seq<option_name, sp, eq, sp, arg> {};
struct step : pegtl::seq<action_name, pegtl::opt<sp, main_arg>, pegtl::star<sp, option>> {};
struct repeat_count : number {};
struct repeat_action : pegtl::seq<kw_repeat, sp, repeat_count, sp, lparen, sp, pegtl::list<step, list_sep>, sp,
                                  rparen> {};
struct state_action : pegtl::sor<repeat_action, step> {};
struct state_name : name {};
struct next_name : name {};
struct state_stmt : pegtl::seq<kw_state, sp, state_name, sp, eq, sp, state_action,
                               pegtl::opt<sp, arrow, sp, next_name>> {};

struct target_name : name {};
struct target : pegtl::sor<kw_ignore, target_name> {};
struct event_name : name {};
struct on_stmt : pegtl::seq<kw_on, sp, pegtl::list<event_name, list_sep>, sp, arrow, sp, target> {};

struct sensor_name : name {};
struct op : pegtl::sor<pegtl::string<'<', '='>, pegtl::string<'>', '='>, pegtl::string<'!', '='>, pegtl::one<'<'>,
                       pegtl::one<'>'>, pegtl::one<'='>> {};
struct cond_value : arg {};
struct when_stmt : pegtl::seq<kw_when, sp, sensor_name, sp, op, sp, cond_value, sp, arrow, sp, target> {};

struct unknown_word : name {};
struct statement : pegtl::sor<behaviour_stmt, param_stmt, report_stmt, state_stmt, on_stmt, when_stmt, unknown_word> {};
// A statement is interpreted once it is complete: at its end (the parser's action on statement_end).
struct statement_end : pegtl::at<pegtl::sor<pegtl::one<';'>, pegtl::eol, pegtl::eof>> {};
struct line : pegtl::seq<sp, pegtl::opt<statement, sp>, pegtl::opt<comment>, statement_end> {};
struct definition : pegtl::seq<pegtl::list<line, sep>, end_of_text> {};

// ---- What a failed rule was expected to be (syntax error messages) ---------------------------------
// In the order a message lists them.
enum class Expect : std::uint8_t {
  none, statement, name, param_name, state_name, value, number, sensor, action, option, event, target, op, eq,
  arrow, comma, dotdot, lparen, rparen, every, count, end_of_statement
};
inline constexpr std::size_t kExpectCount = 22;

constexpr const char* to_text(Expect e) noexcept {
  switch (e) {
    case Expect::none: return "";
    case Expect::statement: return "a statement (behaviour, param, report, state, on, when)";
    case Expect::end_of_statement: return "the end of the statement (';' or a new line)";
    case Expect::name: return "a behaviour name";
    case Expect::param_name: return "a param name";
    case Expect::state_name: return "a state name";
    case Expect::value: return "a value (a number, $param or a word)";
    case Expect::number: return "a number";
    case Expect::sensor: return "a sensor (distance, touch, colour, gyro)";
    case Expect::action: return "an action (run, drive, turn, stop, pause, wait, repeat)";
    case Expect::option: return "an option (name=value)";
    case Expect::event: return "an event (OBSTACLE_DETECTED, PROXIMITY_ALERT, DEVICE_CONNECTED, DEVICE_ERROR)";
    case Expect::target: return "a state name or ignore";
    case Expect::op: return "a comparison (<, <=, >, >=, =, !=)";
    case Expect::eq: return "'='";
    case Expect::arrow: return "'->'";
    case Expect::comma: return "','";
    case Expect::dotdot: return "'..'";
    case Expect::lparen: return "'('";
    case Expect::rparen: return "')'";
    case Expect::every: return "every";
    case Expect::count: return "a repeat count";
  }
  return "";
}

template <typename Rule> struct expect { static constexpr Expect value = Expect::none; };
#define EV3_BHV_EXPECT(rule, e) \
  template <> struct expect<rule> { static constexpr Expect value = Expect::e; }
EV3_BHV_EXPECT(statement, statement);
EV3_BHV_EXPECT(sep, end_of_statement);
EV3_BHV_EXPECT(end_of_text, end_of_statement);
EV3_BHV_EXPECT(behaviour_name, name);
EV3_BHV_EXPECT(param_name, param_name);
EV3_BHV_EXPECT(ref_name, param_name);
EV3_BHV_EXPECT(state_name, state_name);
EV3_BHV_EXPECT(next_name, state_name);
EV3_BHV_EXPECT(param_value, value);
EV3_BHV_EXPECT(arg, value);
EV3_BHV_EXPECT(cond_value, value);
EV3_BHV_EXPECT(range_lo, number);
EV3_BHV_EXPECT(range_hi, number);
EV3_BHV_EXPECT(report_period, number);
EV3_BHV_EXPECT(report_sensor, sensor);
EV3_BHV_EXPECT(sensor_name, sensor);
EV3_BHV_EXPECT(state_action, action);
EV3_BHV_EXPECT(action_name, action);
EV3_BHV_EXPECT(option_name, option);
EV3_BHV_EXPECT(event_name, event);
EV3_BHV_EXPECT(target, target);
EV3_BHV_EXPECT(op, op);
EV3_BHV_EXPECT(eq, eq);
EV3_BHV_EXPECT(arrow, arrow);
EV3_BHV_EXPECT(comma, comma);
EV3_BHV_EXPECT(dotdot, dotdot);
EV3_BHV_EXPECT(lparen, lparen);
EV3_BHV_EXPECT(rparen, rparen);
EV3_BHV_EXPECT(every, every);
EV3_BHV_EXPECT(statement_end, end_of_statement);
EV3_BHV_EXPECT(repeat_count, count);
#undef EV3_BHV_EXPECT

}  // namespace ev3proto::behaviour::grammar
