/// @file rules.hpp
/// @brief Master-side rules the operator can switch on: decisions the master takes on a robot's
/// reports without the operator. Sans-I/O like the cores: a report in, the command to submit out.
///
/// ExploreExploit is the thesis' explore-then-exploit scenario (4.1.3): robots explore; when one's
/// colour sensor (facing the floor) reports the wanted colour in a SENSOR_VALUE, the master sends that
/// robot BEHAVIOUR exploit with the colour, so it stays in the region from then on. A BEHAVIOUR in
/// WORKING replaces the running behaviour and starts it (AgentLogic RecvBehaviour), so no START is
/// needed. Each robot is switched once per explore run, and on_report() keeps that itself: after
/// it returned a robot's command it returns none for that robot until the robot's registry entry
/// shows another behaviour than `explore` (the exploit taken, or the operator's); told to explore
/// again, it is a candidate again. Switching the rule off forgets who was switched.
#pragma once

#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "ev3proto/behaviour/definition.hpp"
#include "ev3proto/master.hpp"

namespace ev3proto {

class ExploreExploit {
 public:
  /// The ev3dev colour sensor mode whose value is a colour code (0 none .. 7 brown).
  static constexpr std::string_view kColourMode = "COL-COLOR";

  /// Switches the rule on for @p colour (a colour name of the language: red, green, ...), with
  /// @p args appended to BEHAVIOUR exploit (`speed=200`). Returns "" or the error.
  std::string switch_on(std::string_view colour, std::vector<std::string> args = {}) {
    for (std::uint8_t c = 1; c <= static_cast<std::uint8_t>(behaviour::Colour::brown); ++c)
      if (behaviour::to_string(static_cast<behaviour::Colour>(c)) == colour) {
        on_ = true;
        code_ = c;
        colour_ = std::string(colour);
        args_ = std::move(args);
        return {};
      }
    return "unknown colour '" + std::string(colour) + "' (black, blue, green, yellow, red, white, brown)";
  }
  void switch_off() {
    on_ = false;
    switched_.clear();
  }
  bool on() const { return on_; }
  const std::string& colour() const { return colour_; }

  /// An operator event of the agent whose registry entry is @p e: the command that switches it,
  /// when the rule is on, the agent runs `explore`, was not switched in this explore run yet and the
  /// event is a SENSOR_VALUE report (port, mode, value) of the colour mode showing the colour.
  std::optional<Command> on_report(const OperatorEvent& r, const RegistryEntry& e) {
    if (e.behaviour != "explore") switched_.erase(r.agent);  // explores no more: a candidate once told again
    if (!on_ || r.kind != OperatorEvent::Kind::report || r.command != MsgType::SENSOR_VALUE) return std::nullopt;
    if (e.behaviour != "explore" || switched_.count(r.agent) != 0) return std::nullopt;
    const std::vector<std::string_view> p = split(r.text);
    if (p.size() != 3 || p[1] != kColourMode || p[2] != std::to_string(code_)) return std::nullopt;
    std::vector<std::string> args{"colour=" + colour_};
    args.insert(args.end(), args_.begin(), args_.end());
    switched_.insert(r.agent);
    return Command::assign("exploit", std::move(args));
  }

 private:
  static std::vector<std::string_view> split(std::string_view t) {
    std::vector<std::string_view> out;
    for (std::size_t at = 0;;) {
      const std::size_t c = t.find(':', at);
      out.push_back(t.substr(at, c == std::string_view::npos ? std::string_view::npos : c - at));
      if (c == std::string_view::npos) return out;
      at = c + 1;
    }
  }

  bool on_ = false;
  std::uint8_t code_ = 0;
  std::string colour_;
  std::vector<std::string> args_;
  std::set<std::uint16_t> switched_;  ///< agents switched in this explore run
};

}  // namespace ev3proto
