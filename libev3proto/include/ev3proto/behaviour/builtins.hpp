/// @file behaviour/builtins.hpp
/// @brief The built-in behaviours (behaviours/*.bhv), written in the language and embedded in the
/// program when it is built (the generated header builtins_text.hpp, cmake/behaviour.cmake).
#pragma once

#include <cstddef>
#include <string_view>

#include "ev3proto/behaviour/builtins_text.hpp"

namespace ev3proto::behaviour {

/// Number of built-in behaviours.
inline constexpr std::size_t kBuiltinCount = sizeof kBuiltins / sizeof kBuiltins[0];

/// The built-in called @p name, or nullptr.
inline const Builtin* find_builtin(std::string_view name) noexcept {
  for (const Builtin& b : kBuiltins)
    if (b.name == name) return &b;
  return nullptr;
}

}  // namespace ev3proto::behaviour
