/// @file behaviour/request.hpp
/// @brief A BEHAVIOUR request as it travels (name, then params) turned into a checked Definition, or
/// the reason it is refused: written once for the master (which checks before it sends) and the
/// robot (which checks on receipt). A built-in name runs its shipped text (behaviours/*.bhv) with
/// the params as `key=value` arguments; `custom` carries the definition in its first param and the
/// arguments after it. No heap, no exceptions.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "ev3proto/behaviour/builtins.hpp"
#include "ev3proto/behaviour/checker.hpp"
#include "ev3proto/behaviour/definition.hpp"
#include "ev3proto/behaviour/model.hpp"
#include "ev3proto/behaviour/parser.hpp"
#include "ev3proto/wire.hpp"

namespace ev3proto::behaviour {

/// The BEHAVIOUR name whose first param is a whole definition in the language.
inline constexpr std::string_view kCustom = "custom";

namespace detail {
inline void write_known_names(Text& why) noexcept {
  why << " (built-ins: ";
  for (std::size_t i = 0; i < kBuiltinCount; ++i) why << (i ? ", " : "") << kBuiltins[i].name;
  why << "; or " << kCustom << " with the definition as its first param)";
}
}  // namespace detail

/// Applies BEHAVIOUR's `key=value` arguments @p args (@p count of them) to the parsed @p def and
/// checks it for a robot of @p model whose plugged devices are @p devices. True when it may run;
/// otherwise false with one line in @p why: the first problem ("argument 'speed=x': ...", "the
/// robot has no colour sensor ..."), and how many more the checker found.
inline bool apply_and_check(Definition& def, const std::string_view* args, std::size_t count, const Model& model,
                            std::uint32_t devices, Text& why) noexcept {
  Diagnostic d;
  if (!apply_args(def, args, count, d)) {
    write(why, d);
    return false;
  }
  static_assert(kMaxFindings > 1);
  Findings f;
  if (!check(def, model, devices, f)) {
    write(why, f.items[0]);
    if (f.count > 1 || f.more) {
      why << " (and " << std::int32_t{f.count - 1};
      why << (f.more ? " or more" : "") << (f.count == 2 && !f.more ? " more problem)" : " more problems)");
    }
    return false;
  }
  return true;
}

/// Resolves BEHAVIOUR @p name with @p params (@p count of them) for a robot of @p model whose plugged
/// devices are @p devices, into @p def: parsed, then apply_and_check(). True when it may run;
/// otherwise false with one line in @p why: the first problem ("line 4 col 12: unknown action 'trun'
/// (...)", or apply_and_check()'s).
inline bool resolve_request(std::string_view name, const std::string_view* params, std::size_t count,
                            const Model& model, std::uint32_t devices, Definition& def, Text& why) noexcept {
  std::string_view text;
  if (name == kCustom) {
    if (count == 0) {
      why << "custom needs the definition as its first param";
      return false;
    }
    text = params[0];
    ++params;
    --count;
  } else if (const Builtin* b = find_builtin(name)) {
    text = b->text;
  } else {
    why << "unknown behaviour '" << name << "'";
    detail::write_known_names(why);
    return false;
  }
  Diagnostic d;
  if (!parse(text, def, d)) {
    write(why, d);
    return false;
  }
  return apply_and_check(def, params, count, model, devices, why);
}

/// The size of the BEHAVIOUR custom datagram carrying @p text, with the longest header (msgid
/// 2^32-1), encoded into @p buf; 0 when it does not fit in kMaxDatagram bytes.
inline std::size_t custom_datagram_size(std::string_view text, char (&buf)[kMaxDatagram]) noexcept {
  const std::string_view params[] = {kCustom, text};
  const EncodeResult r = encode_parts(1, 49999, 4294967295u, 7, params, 2, buf, sizeof buf);
  return r.ok() ? r.size : 0;
}

}  // namespace ev3proto::behaviour
