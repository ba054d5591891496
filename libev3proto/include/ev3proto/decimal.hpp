/// @file decimal.hpp
/// @brief The one integer-to-text routine of the library: numbers in decimal for the wire codec
///        (header fields and number params), the election's params, the durable state's text, the
///        robot's texts and the behaviour printer. No heap, no exceptions, usable in constexpr.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace ev3proto {

/// Most characters write_int() writes ('-' and 19 digits, or 20 digits of a magnitude).
inline constexpr std::size_t kMaxIntText = 20;

/// Number of decimal digits of the unsigned @p v (1 for 0).
template <typename U>
constexpr std::size_t decimal_digits(U v) noexcept {
  std::size_t n = 1;
  for (; v >= 10u; v /= 10u) ++n;
  return n;
}

/// Writes the unsigned @p v in canonical decimal ("0", or no leading zero) at @p out, which has
/// room for decimal_digits(v) bytes; returns the end. The type is the caller's: a 32-bit value
/// stays in 32-bit arithmetic (the EV3 divides 64-bit numbers in software).
template <typename U>
constexpr char* write_decimal(char* out, U v) noexcept {
  char* const end = out + decimal_digits(v);
  char* p = end;
  do {
    *--p = static_cast<char>('0' + static_cast<int>(v % 10u));
    v /= 10u;
  } while (v != 0u);
  return end;
}

/// Writes @p v in decimal, with '-' when negative ("-42"), at @p out (room for kMaxIntText bytes);
/// returns the end.
constexpr char* write_int(char* out, std::int64_t v) noexcept {
  const bool neg = v < 0;
  const std::uint64_t u = neg ? std::uint64_t{0} - static_cast<std::uint64_t>(v) : static_cast<std::uint64_t>(v);
  if (neg) *out++ = '-';
  return write_decimal(out, u);
}

/// Writes @p raw / 10^@p decimals at @p out: the integer part, then '.' and @p decimals digits
/// ("18.3", "-0.05"); with @p trim, the fraction's trailing zeros are left out, and the point too
/// when nothing is left of it ("1.5", "2"). @p out has room for 2 * kMaxIntText + 2 bytes; returns
/// the end.
constexpr char* write_fixed(char* out, std::int64_t raw, unsigned decimals, bool trim) noexcept {
  if (decimals == 0) return write_int(out, raw);
  std::uint64_t scale = 1;
  for (unsigned i = 0; i < decimals; ++i) scale *= 10u;
  const bool neg = raw < 0;
  const std::uint64_t u = neg ? std::uint64_t{0} - static_cast<std::uint64_t>(raw) : static_cast<std::uint64_t>(raw);
  if (neg) *out++ = '-';
  out = write_decimal(out, u / scale);
  std::uint64_t frac = u % scale;
  if (trim && frac == 0) return out;
  *out++ = '.';
  for (std::uint64_t s = scale / 10u; s > 0 && !(trim && frac == 0); s /= 10u) {
    *out++ = static_cast<char>('0' + static_cast<int>(frac / s));
    frac %= s;
  }
  return out;
}

/// @p v in decimal into @p buf: a datagram parameter.
inline std::string_view decimal(std::uint32_t v, char (&buf)[10]) noexcept {
  char* e = write_decimal(buf, v);
  return std::string_view(buf, static_cast<std::size_t>(e - buf));
}

}  // namespace ev3proto
