/// @file text.hpp
/// @brief Fixed-capacity text and the strict parsers the robot logic reads sysfs values with.
///
/// sysfs attributes are short ASCII texts ending in a newline ("614\n", "running holding\n",
/// "US-DIST-CM US-DIST-IN ...\n", "none [timer] heartbeat\n"). The robot logic parses them itself
/// (the device layer only moves bytes), so a garbage value is found here, in pure code, and becomes
/// a clear reason, never a crash. No heap, no exceptions: texts live in fixed buffers.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "../decimal.hpp"

namespace ev3proto::robot {

/// A text of at most N - 1 characters in place (longer appends are cut and flag overflow()).
template <std::size_t N>
class Text {
 public:
  static_assert(N >= 2 && N <= 255, "Text holds 1..254 characters");
  constexpr Text() noexcept = default;
  /// The text @p s (cut to the capacity).
  constexpr explicit Text(std::string_view s) noexcept { append(s); }

  /// The characters as a view (valid while the Text lives and is not changed).
  constexpr std::string_view view() const noexcept { return std::string_view(buf_, len_); }
  /// Implicit view, so a Text can be compared with and passed as a string_view.
  constexpr operator std::string_view() const noexcept { return view(); }
  constexpr std::size_t size() const noexcept { return len_; }
  constexpr bool empty() const noexcept { return len_ == 0; }
  /// True when something appended did not fit.
  constexpr bool overflow() const noexcept { return overflow_; }
  constexpr void clear() noexcept {
    len_ = 0;
    overflow_ = false;
  }

  /// Appends @p s (as much as fits).
  constexpr Text& append(std::string_view s) noexcept {
    for (char c : s) {
      if (len_ + 1u >= N) {
        overflow_ = true;
        break;
      }
      buf_[len_++] = c;
    }
    return *this;
  }
  /// Appends one character.
  constexpr Text& append(char c) noexcept { return append(std::string_view(&c, 1)); }
  /// Appends a decimal integer ("-42").
  constexpr Text& append_int(std::int64_t v) noexcept { return append_fixed(v, 0); }
  /// Appends @p raw / 10^decimals with exactly @p decimals digits after the point ("18.3", "-0.05").
  constexpr Text& append_fixed(std::int64_t raw, unsigned decimals) noexcept {
    char d[2 * kMaxIntText + 2] = {};
    return append(std::string_view(d, static_cast<std::size_t>(write_fixed(d, raw, decimals, false) - d)));
  }

 private:
  char buf_[N] = {};
  std::uint8_t len_ = 0;
  bool overflow_ = false;
};

/// A reason for a refusal or an error, in words ("speed_sp 1200 is above outB's max_speed 1050").
using ReasonText = Text<128>;

/// @p s without the trailing newline(s) sysfs puts after a value.
constexpr std::string_view chomp(std::string_view s) noexcept {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

/// Parses a sysfs integer: an optional '-', 1..10 digits, an optional trailing newline; nothing
/// else (no spaces, no '+', no hex). False (and @p out unchanged) for anything else or outside int32.
constexpr bool parse_int(std::string_view s, std::int32_t& out) noexcept {
  s = chomp(s);
  bool neg = false;
  if (!s.empty() && s.front() == '-') {
    neg = true;
    s.remove_prefix(1);
  }
  if (s.empty() || s.size() > 10) return false;
  std::int64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + (c - '0');
  }
  if (neg) v = -v;
  if (v < INT32_MIN || v > INT32_MAX) return false;
  out = static_cast<std::int32_t>(v);
  return true;
}

/// Parses a decimal number with at most @p decimals digits after the point ("0.25", "-12", "3.")
/// into raw = value x 10^decimals. False for anything else, more digits, or outside int32.
constexpr bool parse_decimal(std::string_view s, unsigned decimals, std::int32_t& raw) noexcept {
  s = chomp(s);
  bool neg = false;
  if (!s.empty() && (s.front() == '-' || s.front() == '+')) {
    neg = s.front() == '-';
    s.remove_prefix(1);
  }
  std::int64_t v = 0;
  std::size_t digits = 0, frac = 0;
  bool point = false;
  for (char c : s) {
    if (c == '.' && !point) {
      point = true;
      continue;
    }
    if (c < '0' || c > '9') return false;
    if (point && ++frac > decimals) return false;
    if (++digits > 12) return false;
    v = v * 10 + (c - '0');
  }
  if (digits == 0) return false;
  for (std::size_t i = frac; i < decimals; ++i) v *= 10;
  if (neg) v = -v;
  if (v < INT32_MIN || v > INT32_MAX) return false;
  raw = static_cast<std::int32_t>(v);
  return true;
}

/// Splits a space-separated sysfs list ("coast brake hold\n") into tokens. Usage:
///   for (Tokens t(text); !t.done(); t.next()) use(t.token(), t.selected());
/// A token written "[timer]" (the LED class marks the active trigger so) is given without the
/// brackets, with selected() true.
class Tokens {
 public:
  constexpr explicit Tokens(std::string_view s) noexcept : rest_(chomp(s)) { next(); }
  constexpr bool done() const noexcept { return done_; }
  constexpr std::string_view token() const noexcept { return tok_; }
  constexpr bool selected() const noexcept { return selected_; }
  constexpr void next() noexcept {
    while (!rest_.empty() && (rest_.front() == ' ' || rest_.front() == '\t')) rest_.remove_prefix(1);
    if (rest_.empty()) {
      done_ = true;
      tok_ = {};
      return;
    }
    std::size_t n = 0;
    while (n < rest_.size() && rest_[n] != ' ' && rest_[n] != '\t') ++n;
    tok_ = rest_.substr(0, n);
    rest_.remove_prefix(n);
    selected_ = tok_.size() >= 2 && tok_.front() == '[' && tok_.back() == ']';
    if (selected_) tok_ = tok_.substr(1, tok_.size() - 2);
  }

 private:
  std::string_view rest_, tok_;
  bool done_ = false, selected_ = false;
};

/// True when every character of @p s is printable ASCII without spaces (a sane sysfs word).
constexpr bool is_word(std::string_view s) noexcept {
  if (s.empty()) return false;
  for (char c : s)
    if (c <= ' ' || c > '~') return false;
  return true;
}

/// Appends a value seen in a device file to a reason, quoted, printable, at most 24 characters.
template <std::size_t N>
constexpr void append_quoted(Text<N>& t, std::string_view v) noexcept {
  v = chomp(v);
  t.append('\'');
  std::size_t i = 0;
  for (; i < v.size() && i < 24; ++i) {
    const char c = v[i];
    t.append(c >= ' ' && c <= '~' ? c : '?');
  }
  if (i < v.size()) t.append("...");
  t.append('\'');
}

}  // namespace ev3proto::robot
