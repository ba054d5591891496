/// @file wire.hpp
/// @brief Wire format v1: decode and encode datagrams (docs/protocol.md is normative).
///
/// Header-only, C++17, no exceptions, no heap, no I/O, no mutable globals. decode() never reads
/// outside the datagram it is given; encode() never writes more than the caller's capacity.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string_view>
#include <type_traits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__) && !defined(EV3PROTO_NO_AVX2)
#include <immintrin.h>
/// Defined where decode() may pick an AVX2 classifier at run time (x86-64 with GCC or Clang; define
/// EV3PROTO_NO_AVX2 to build without it).
#define EV3PROTO_AVX2_DISPATCH 1
#endif

#include "messages.hpp"

namespace ev3proto {

/// Most bytes a datagram may have.
inline constexpr std::size_t kMaxDatagram = 4096;

/// Why a datagram (or a message to encode) is rejected; `ok` when it is not.
/// The order of the enumerators has no meaning; docs/protocol.md fixes the order of the checks.
enum class Reason : std::uint8_t {
  ok = 0,             ///< Accepted.
  empty,              ///< "empty": no bytes at all.
  too_long,           ///< "too long": more than 4096 bytes (or more than the caller's buffer).
  too_few_fields,     ///< "too few fields": a header field or a required param is missing.
  bad_number,         ///< "bad number": not a canonical decimal number.
  out_of_range,       ///< "out of range": a number above its maximum, type 0, or not a state.
  unknown_type,       ///< "unknown type": a type in 1..255 the table does not define.
  bad_escape,         ///< "bad escape": malformed or non-canonical %XX escape.
  non_printable_byte, ///< "non-printable byte": a raw param byte outside 0x20..0x7E.
  too_many_params,    ///< "too many params": more than 32 params or than the type's max.
};

/// The reason's name exactly as docs/protocol.md spells it ("bad escape"); "ok" for Reason::ok and
/// "" for a value that is not an enumerator.
constexpr std::string_view to_string(Reason r) noexcept {
  switch (r) {
    case Reason::ok: return "ok";
    case Reason::empty: return "empty";
    case Reason::too_long: return "too long";
    case Reason::too_few_fields: return "too few fields";
    case Reason::bad_number: return "bad number";
    case Reason::out_of_range: return "out of range";
    case Reason::unknown_type: return "unknown type";
    case Reason::bad_escape: return "bad escape";
    case Reason::non_printable_byte: return "non-printable byte";
    case Reason::too_many_params: return "too many params";
  }
  return {};
}

/// Field index of the sender (rejections carry one of these, or kFieldParam0 + i for param i).
inline constexpr std::uint8_t kFieldSender = 0;
/// Field index of the receiver.
inline constexpr std::uint8_t kFieldReceiver = 1;
/// Field index of the msgid.
inline constexpr std::uint8_t kFieldMsgid = 2;
/// Field index of the type.
inline constexpr std::uint8_t kFieldType = 3;
/// Field index of the first param; param i is kFieldParam0 + i.
inline constexpr std::uint8_t kFieldParam0 = 4;

/// Outcome of decode(): Reason::ok, or the first problem and the field it is in.
struct DecodeResult {
  Reason reason = Reason::ok; ///< Reason::ok when the datagram was accepted.
  std::uint8_t field = 0;     ///< Field index of the problem (0 when accepted).

  /// True when the datagram was accepted.
  constexpr bool ok() const noexcept { return reason == Reason::ok; }
  /// True when the datagram was accepted.
  constexpr explicit operator bool() const noexcept { return ok(); }
  /// Field-by-field equality.
  friend constexpr bool operator==(DecodeResult a, DecodeResult b) noexcept {
    return a.reason == b.reason && a.field == b.field;
  }
  /// Field-by-field inequality.
  friend constexpr bool operator!=(DecodeResult a, DecodeResult b) noexcept { return !(a == b); }
};

/// Outcome of encode(): the number of bytes written, or why nothing usable was written.
struct EncodeResult {
  std::size_t size = 0;       ///< Bytes written when ok(); 0 otherwise.
  Reason reason = Reason::ok; ///< Reason::ok when the message was encoded.
  std::uint8_t field = 0;     ///< Field index of the problem, as decode() would report it.

  /// True when the message was encoded.
  constexpr bool ok() const noexcept { return reason == Reason::ok; }
  /// True when the message was encoded.
  constexpr explicit operator bool() const noexcept { return ok(); }
};

class Message;
inline DecodeResult decode(std::string_view datagram, Message& out) noexcept;

/// A decoded (or to-be-encoded) message: header fields plus up to 32 params, stored unescaped in the
/// message's own fixed buffer. Self-contained and trivially copyable (no pointers into the datagram).
/// Construction does not clear the 4 KiB buffer; only the bytes of the params present are meaningful.
class Message {
 public:
  /// Bytes available for the unescaped values of all params together.
  static constexpr std::size_t kCapacity = kMaxDatagram;

  std::uint16_t sender = 0;      ///< Sender id (0..65535).
  std::uint16_t receiver = 0;    ///< Receiver id; 0 = broadcast, 1 = the master.
  std::uint32_t msgid = 0;       ///< Per-sender message id.
  MsgType type = MsgType::PING;  ///< Message type (may hold an undefined value; encode() refuses it).

  /// An empty PING from 0 to 0 with msgid 0 and no params.
  Message() noexcept {}  // NOLINT: deliberately leaves data_ and ends_ uninitialised (performance)
  /// A message with the given header and no params.
  Message(std::uint16_t from, std::uint16_t to, std::uint32_t id, MsgType t) noexcept
      : sender(from), receiver(to), msgid(id), type(t) {}

  /// Number of params.
  std::size_t param_count() const noexcept { return count_; }

  /// The unescaped value of param @p i; empty if @p i >= param_count().
  std::string_view param(std::size_t i) const noexcept {
    if (i >= count_) return {};
    return std::string_view(data_ + begins_[i], static_cast<std::size_t>(ends_[i] - begins_[i]));
  }

  /// Bytes of the internal buffer in use (the values, and after decode() the separators between them).
  std::size_t params_size() const noexcept { return count_ == 0 ? 0u : ends_[count_ - 1u]; }

  /// Removes all params (the header is kept).
  void clear_params() noexcept { count_ = 0; }

  /// Appends a param (any bytes; escaping happens in encode()). Returns false, changing nothing, if
  /// the message already has 32 params or the buffer has no room for @p value.
  bool add_param(std::string_view value) noexcept {
    const std::size_t used = params_size();
    if (count_ >= kMaxParams || value.size() > kCapacity - used) return false;
    if (!value.empty()) std::memcpy(data_ + used, value.data(), value.size());
    begins_[count_] = static_cast<std::uint16_t>(used);
    ends_[count_++] = static_cast<std::uint16_t>(used + value.size());
    return true;
  }

  /// Appends a number param in canonical decimal. Returns false as add_param(std::string_view).
  bool add_param_u32(std::uint32_t value) noexcept {
    char tmp[10];
    std::size_t n = 0;
    do {
      tmp[n++] = static_cast<char>('0' + value % 10u);
      value /= 10u;
    } while (value != 0);
    char digits[10];
    for (std::size_t k = 0; k < n; ++k) digits[k] = tmp[n - 1u - k];
    return add_param(std::string_view(digits, n));
  }

  /// Appends an agent state ("WORKING"). Returns false as add_param(std::string_view).
  bool add_param_state(AgentState s) noexcept { return add_param(to_string(s)); }

  /// Param @p i as a canonical number 0..4294967295, or nullopt if it is missing or not one.
  std::optional<std::uint32_t> param_u32(std::size_t i) const noexcept;
  /// Param @p i as a canonical number 0..65535, or nullopt if it is missing or not one.
  std::optional<std::uint16_t> param_u16(std::size_t i) const noexcept;
  /// Param @p i as an agent state, or nullopt if it is missing or not one.
  std::optional<AgentState> param_state(std::size_t i) const noexcept;

  /// Equal header fields and equal param values (the unused part of the buffer is ignored).
  friend bool operator==(const Message& a, const Message& b) noexcept {
    if (a.sender != b.sender || a.receiver != b.receiver || a.msgid != b.msgid || a.type != b.type ||
        a.count_ != b.count_)
      return false;
    for (std::size_t i = 0; i < a.count_; ++i)
      if (a.param(i) != b.param(i)) return false;
    return true;
  }
  /// Negation of operator==.
  friend bool operator!=(const Message& a, const Message& b) noexcept { return !(a == b); }

 private:
  friend DecodeResult decode(std::string_view datagram, Message& out) noexcept;

  std::uint8_t count_ = 0;           // number of params
  std::uint16_t begins_[kMaxParams]; // offset of param i's first byte in data_
  std::uint16_t ends_[kMaxParams];   // offset just past param i's last byte in data_
  char data_[kCapacity];             // unescaped values (decode() keeps the separators between them)
};

static_assert(std::is_trivially_copyable<Message>::value, "Message must stay trivially copyable");

namespace detail {

/// Value of an upper-case hex digit, or -1 (lower-case is not canonical and not accepted).
constexpr int upper_hex_value(unsigned char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// True for a byte that a param must carry as a %XX escape: ':' '%' and bytes outside 0x20..0x7E.
constexpr bool must_escape(unsigned char c) noexcept {
  return c < 0x20 || c > 0x7E || c == ':' || c == '%';
}

/// upper_hex_value() of every byte, as a table: decode() looks up two per escape, without branches.
struct HexTable {
  signed char v[256];
  constexpr HexTable() : v{} {
    for (int c = 0; c < 256; ++c) v[c] = static_cast<signed char>(upper_hex_value(static_cast<unsigned char>(c)));
  }
};
inline constexpr HexTable kHexTable{};

/// must_escape() of every byte, as 256 bits: decode() tests an escape's byte without branches.
struct EscapeBits {
  std::uint64_t w[4];
  constexpr EscapeBits() : w{} {
    for (unsigned c = 0; c < 256; ++c)
      if (must_escape(static_cast<unsigned char>(c))) w[c >> 6] |= std::uint64_t{1} << (c & 63u);
  }
  /// must_escape(@p c).
  constexpr bool has(unsigned char c) const noexcept { return (w[c >> 6] >> (c & 63u)) & 1u; }
};
inline constexpr EscapeBits kEscapeBits{};

/// Checks that [p, e) is a canonical decimal number no greater than @p max.
/// Returns ok, bad_number or out_of_range; stores the value in @p value when ok.
constexpr Reason parse_number(const char* p, const char* e, std::uint32_t max,
                              std::uint32_t& value) noexcept {
  const std::size_t n = static_cast<std::size_t>(e - p);
  if (n == 0) return Reason::bad_number;
  if (n > 1 && *p == '0') return Reason::bad_number;
  std::uint64_t v = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const unsigned d = static_cast<unsigned>(static_cast<unsigned char>(p[k])) - unsigned{'0'};
    if (d > 9u) return Reason::bad_number;
    if (k < 11) v = v * 10u + d;  // 11 digits without a leading zero already exceed any maximum
  }
  if (v > max) return Reason::out_of_range;
  value = static_cast<std::uint32_t>(v);
  return Reason::ok;
}

/// Checks a param's unescaped value against its kind (text always passes).
inline Reason check_kind(ParamKind kind, std::string_view v) noexcept {
  std::uint32_t n = 0;
  AgentState s = AgentState::IDLE;
  switch (kind) {
    case ParamKind::text: return Reason::ok;
    case ParamKind::u16: return parse_number(v.data(), v.data() + v.size(), 0xFFFFu, n);
    case ParamKind::u32: return parse_number(v.data(), v.data() + v.size(), 0xFFFFFFFFu, n);
    case ParamKind::state: return parse_state(v, s) ? Reason::ok : Reason::out_of_range;
  }
  return Reason::ok;
}

/// Number of decimal digits of @p v.
constexpr std::size_t decimal_digits(std::uint32_t v) noexcept {
  std::size_t n = 1;
  while (v >= 10u) {
    v /= 10u;
    ++n;
  }
  return n;
}

/// Writes @p v in decimal at @p out (which has room for decimal_digits(v) bytes); returns the end.
inline char* write_decimal(char* out, std::uint32_t v) noexcept {
  const std::size_t n = decimal_digits(v);
  char* p = out + n;
  do {
    *--p = static_cast<char>('0' + v % 10u);
    v /= 10u;
  } while (v != 0);
  return out + n;
}

/// A DecodeResult for a problem in field @p field.
constexpr DecodeResult fail(Reason r, std::size_t field) noexcept {
  return DecodeResult{r, static_cast<std::uint8_t>(field)};
}

/// Bytes of the blocks decode() classifies at once (one bit of a 64-bit mask per byte).
inline constexpr std::size_t kBlock = 64;
/// Granularity of the last block: the param region is padded to a multiple of this.
inline constexpr std::size_t kChunk = 16;

/// Reference classifier, one byte at a time: for the @p len bytes at @p b (at most 64), bit i of
/// @p colon is set where b[i] is ':', bit i of @p special where b[i] may not stand raw in a param
/// ('%', below 0x20, above 0x7E).
inline void classify_scalar(const unsigned char* b, std::size_t len, std::uint64_t& colon,
                            std::uint64_t& special) noexcept {
  std::uint64_t c = 0, sp = 0;
  for (std::size_t i = 0; i < len; ++i) {
    const unsigned char x = b[i];
    c |= std::uint64_t{x == ':'} << i;
    sp |= std::uint64_t{x == '%' || x < 0x20 || x > 0x7E} << i;
  }
  colon = c;
  special = sp;
}

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
/// classify_scalar() of the 8 bytes of the little-endian word @p x: exact SWAR (no carry crosses a
/// byte), each byte's high bit compressed to one bit with a multiply. Bit i of @p colon / @p special
/// is byte i.
inline void classify_word(std::uint64_t x, std::uint64_t& colon, std::uint64_t& special) noexcept {
  constexpr std::uint64_t ones = 0x0101010101010101ull;
  constexpr std::uint64_t low7 = 0x7F7F7F7F7F7F7F7Full;
  constexpr std::uint64_t highs = 0x8080808080808080ull;
  auto zero_bytes = [](std::uint64_t t) noexcept { return ~(((t & low7) + low7) | t | low7); };
  auto compress = [](std::uint64_t m) noexcept {
    return static_cast<std::uint64_t>(((m >> 7) * 0x0102040810204080ull) >> 56);
  };
  const std::uint64_t lo = x & low7;
  const std::uint64_t below = ~((lo + 0x60u * ones) | x) & highs;  // byte < 0x20
  const std::uint64_t above = ((lo + ones) | x) & highs;          // byte >= 0x7F
  const std::uint64_t percent = zero_bytes(x ^ (0x25u * ones));
  colon = compress(zero_bytes(x ^ (0x3Au * ones)));
  special = compress(below | above | percent);
}

/// classify_scalar() 8 bytes at a time (@p len a multiple of 8) with classify_word(). Portable; the
/// EV3 (ARMv5TE) takes this path.
inline void classify_swar(const unsigned char* b, std::size_t len, std::uint64_t& colon,
                          std::uint64_t& special) noexcept {
  std::uint64_t c = 0, sp = 0;
  for (std::size_t k = 0; k < len / 8u; ++k) {
    std::uint64_t x, wc, ws;
    std::memcpy(&x, b + 8u * k, sizeof x);
    classify_word(x, wc, ws);
    c |= wc << (8u * k);
    sp |= ws << (8u * k);
  }
  colon = c;
  special = sp;
}
#endif

#if defined(__SSE2__)
/// classify_scalar() 16 bytes at a time (@p len a multiple of 16) with SSE2 (every x86-64 has it).
inline void classify_sse2(const unsigned char* b, std::size_t len, std::uint64_t& colon,
                          std::uint64_t& special) noexcept {
  const __m128i k_colon = _mm_set1_epi8(':');
  const __m128i k_percent = _mm_set1_epi8('%');
  // Adding 0x60 maps 0x20..0x7E onto -128..-34 (signed); every other byte lands above -34.
  const __m128i k_shift = _mm_set1_epi8(0x60);
  const __m128i k_limit = _mm_set1_epi8(-34);
  std::uint64_t c = 0, sp = 0;
  for (std::size_t k = 0; k < len / 16u; ++k) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + 16u * k));
    const __m128i outside = _mm_cmpgt_epi8(_mm_add_epi8(v, k_shift), k_limit);
    const __m128i sv = _mm_or_si128(outside, _mm_cmpeq_epi8(v, k_percent));
    c |= std::uint64_t{static_cast<std::uint16_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, k_colon)))} << (16u * k);
    sp |= std::uint64_t{static_cast<std::uint16_t>(_mm_movemask_epi8(sv))} << (16u * k);
  }
  colon = c;
  special = sp;
}
#endif

/// The classifier decode() uses: SSE2 where the compiler targets it, else SWAR on little-endian
/// hosts, else the scalar reference. @p len is a multiple of 16, at most 64.
inline void classify_block(const unsigned char* b, std::size_t len, std::uint64_t& colon,
                           std::uint64_t& special) noexcept {
#if defined(__SSE2__)
  classify_sse2(b, len, colon, special);
#elif defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  classify_swar(b, len, colon, special);
#else
  classify_scalar(b, len, colon, special);
#endif
}

/// Largest value of each header field (sender, receiver, msgid, type); the type must also not be 0.
inline constexpr std::uint32_t kHeaderMax[4] = {0xFFFFu, 0xFFFFu, 0xFFFFFFFFu, 0xFFu};

/// The header of decode() byte by byte, as docs/protocol.md checks it: four canonical numbers within
/// kHeaderMax (the type not 0) separated by ':', in the @p len bytes at @p datagram. On success stores
/// them in @p hdr and the offset of param 0 in @p params_at (0 when no ':' follows the type: no
/// params) and returns ok; else the first problem and its field.
inline DecodeResult header_bytewise(const char* datagram, std::size_t len, std::uint32_t (&hdr)[4],
                                    std::size_t& params_at) noexcept {
  const char* p = datagram;
  const char* const e = datagram + len;
  params_at = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    const char* q = p;
    while (q != e && *q != ':') ++q;  // the field: up to the next ':' or the end
    const Reason r = parse_number(p, q, kHeaderMax[k], hdr[k]);
    if (r != Reason::ok) return fail(r, k);
    if (k == kFieldType && hdr[k] == 0) return fail(Reason::out_of_range, k);
    if (q == e) {
      if (k < 3) return fail(Reason::too_few_fields, k + 1);
    } else {
      p = q + 1;  // past the ':'
      if (k == 3) params_at = static_cast<std::size_t>(p - datagram);
    }
  }
  return DecodeResult{};
}

#if defined(__SSE2__)
/// The header of decode() at once, for a datagram of at least 16 bytes whose first 16 hold the four
/// header fields and the ':' after the type: one load, the ':' and digit bytes as two masks, every
/// check as mask arithmetic. Returns false (and decode() takes the byte-at-a-time path, which names
/// the problem) unless the four fields are canonical numbers within kHeaderMax and the type is not 0;
/// then stores them in @p hdr and the offset of param 0 in @p params_at, and returns true.
inline bool header_sse2(const char* p, std::uint32_t (&hdr)[4], std::size_t& params_at) noexcept {
  const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
  const __m128i t = _mm_sub_epi8(v, _mm_set1_epi8('0'));
  const unsigned colon = static_cast<unsigned>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, _mm_set1_epi8(':'))));
  const unsigned digit =
      static_cast<unsigned>(_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_min_epu8(t, _mm_set1_epi8(9)), t)));
  const unsigned zero = static_cast<unsigned>(_mm_movemask_epi8(_mm_cmpeq_epi8(t, _mm_setzero_si128())));
  const unsigned m1 = colon & (colon - 1u), m2 = m1 & (m1 - 1u), m3 = m2 & (m2 - 1u);
  if (m3 == 0) return false;  // fewer than four ':' in the first 16 bytes
  const unsigned c0 = static_cast<unsigned>(__builtin_ctz(colon)), c1 = static_cast<unsigned>(__builtin_ctz(m1));
  const unsigned c2 = static_cast<unsigned>(__builtin_ctz(m2)), c3 = static_cast<unsigned>(__builtin_ctz(m3));
  const unsigned field = (1u << c3) - 1u;           // the bytes before the ':' after the type
  const unsigned starts = (1u | (colon << 1)) & field;  // the first byte of each field
  // Only digits and ':' in the header; no field empty (a start that is a ':'); no leading zero;
  // lengths within what each maximum allows (5, 5, 10, 3 digits).
  if (((digit | colon) & field) != field || (starts & colon) != 0 || (starts & zero & (digit >> 1)) != 0 ||
      c0 > 5u || c1 - c0 > 6u || c2 - c1 > 11u || c3 - c2 > 4u)
    return false;
  auto number = [p](unsigned from, unsigned to) noexcept {  // digits known: no check per byte
    std::uint64_t x = 0;
    for (unsigned i = from; i < to; ++i) x = x * 10u + static_cast<unsigned>(static_cast<unsigned char>(p[i]) - '0');
    return x;
  };
  const std::uint64_t a = number(0, c0), b = number(c0 + 1u, c1), c = number(c1 + 1u, c2),
                      ty = number(c2 + 1u, c3);
  if (a > kHeaderMax[0] || b > kHeaderMax[1] || c > kHeaderMax[2] || ty > kHeaderMax[3] || ty == 0)
    return false;
  hdr[0] = static_cast<std::uint32_t>(a);
  hdr[1] = static_cast<std::uint32_t>(b);
  hdr[2] = static_cast<std::uint32_t>(c);
  hdr[3] = static_cast<std::uint32_t>(ty);
  params_at = c3 + 1u;
  return true;
}
#endif

/// Copies the @p n (1 to 15) bytes at @p src to @p d with two overlapping loads and stores.
inline void copy_short(unsigned char* d, const unsigned char* src, std::size_t n) noexcept {
  if (n >= 8) {
    std::uint64_t a, b;
    std::memcpy(&a, src, 8);
    std::memcpy(&b, src + n - 8u, 8);
    std::memcpy(d, &a, 8);
    std::memcpy(d + n - 8u, &b, 8);
  } else if (n >= 4) {
    std::uint32_t a, b;
    std::memcpy(&a, src, 4);
    std::memcpy(&b, src + n - 4u, 4);
    std::memcpy(d, &a, 4);
    std::memcpy(d + n - 4u, &b, 4);
  } else if (n != 0) {
    const unsigned char a = src[0], b = src[n / 2u], c = src[n - 1u];
    d[0] = a;
    d[n / 2u] = b;
    d[n - 1u] = c;
  }
}

#if defined(__SSE2__)
/// The small-region path of decode() (PING, reports): for @p n <= 64 param bytes at @p src whose
/// 16 bytes before src + n are readable (the datagram is at least 16 bytes long; some of them may be
/// header bytes), copies the n bytes to @p d and classifies them into one pair of masks (no bit at n
/// or above), all from registers loaded from @p src: a partial chunk is loaded as the 16 bytes ending
/// at src + n and its masks shifted down. Nothing is padded and nothing just stored is loaded again
/// (a 16-byte load of bytes written by smaller stores stalls store forwarding).
inline void copy_classify_small_sse2(const unsigned char* src, std::size_t n, unsigned char* d,
                                     std::uint64_t& colon, std::uint64_t& special) noexcept {
  const __m128i k_colon = _mm_set1_epi8(':');
  const __m128i k_percent = _mm_set1_epi8('%');
  const __m128i k_shift = _mm_set1_epi8(0x60);  // as in classify_sse2()
  const __m128i k_limit = _mm_set1_epi8(-34);
  auto colons_of = [&](__m128i v) noexcept {
    return std::uint64_t{static_cast<std::uint16_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, k_colon)))};
  };
  auto specials_of = [&](__m128i v) noexcept {
    const __m128i outside = _mm_cmpgt_epi8(_mm_add_epi8(v, k_shift), k_limit);
    return std::uint64_t{static_cast<std::uint16_t>(
        _mm_movemask_epi8(_mm_or_si128(outside, _mm_cmpeq_epi8(v, k_percent))))};
  };
  std::uint64_t c = 0, sp = 0;
  std::size_t k = 0;
  for (; n - k >= kChunk; k += kChunk) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + k));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(d + k), v);
    c |= colons_of(v) << k;
    sp |= specials_of(v) << k;
  }
  if (k != n) {  // 1 to 15 bytes left: the 16 bytes ending at src + n
    const std::size_t drop = kChunk - (n - k);
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + n - kChunk));
    if (k != 0) _mm_storeu_si128(reinterpret_cast<__m128i*>(d + n - kChunk), v);
    else copy_short(d, src, n);
    c |= (colons_of(v) >> drop) << k;
    sp |= (specials_of(v) >> drop) << k;
  }
  colon = c;
  special = sp;
}
#endif

/// Pads the @p n bytes at @p d with a plain byte ('A') up to the next multiple of 16: a fixed 16-byte
/// store (one instruction) where it fits in the 4096-byte message buffer, the exact length at its end.
inline void pad_region(unsigned char* d, std::size_t n) noexcept {
  const std::size_t padded = (n + kChunk - 1u) & ~(kChunk - 1u);
  if (n + kChunk <= kMaxDatagram) std::memset(d + n, 'A', kChunk);
  else std::memset(d + n, 'A', padded - n);
}

/// Copies the @p n param bytes at @p src to @p d, pads them (pad_region()) and classifies the padded
/// region: one pair of classify_block() masks per 64-byte block into @p colons and @p specials.
/// Portable version: one memcpy, then the blocks.
inline void copy_classify_generic(const unsigned char* src, std::size_t n, unsigned char* d,
                                  std::uint64_t* colons, std::uint64_t* specials) noexcept {
  if (n != 0) std::memcpy(d, src, n);
  pad_region(d, n);
  const std::size_t padded = (n + kChunk - 1u) & ~(kChunk - 1u);
  for (std::size_t base = 0; base < padded; base += kBlock)
    classify_block(d + base, padded - base < kBlock ? padded - base : kBlock, *colons++, *specials++);
}

/// Bit i set where p[i] must be escaped in a param (':' '%' and bytes outside 0x20..0x7E), for the
/// 16 bytes at @p p.
inline std::uint32_t escape_mask16(const char* p) noexcept {
  std::uint64_t colon = 0, special = 0;
  classify_block(reinterpret_cast<const unsigned char*>(p), 16, colon, special);
  return static_cast<std::uint32_t>(colon | special);
}

/// Bit i set where p[i] must be escaped, for the @p n (0 to 15) bytes at @p p; reads nothing
/// outside them (two overlapping 8-byte words where the host is little-endian and n >= 8, else byte
/// by byte).
inline std::uint32_t escape_mask_short(const char* p, std::size_t n) noexcept {
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  if (n >= 8) {  // (shorter: the byte loop below was measured faster)
    std::uint64_t a, b, ca, sa, cb, sb;
    std::memcpy(&a, p, 8);
    std::memcpy(&b, p + n - 8u, 8);
    classify_word(a, ca, sa);
    classify_word(b, cb, sb);
    return static_cast<std::uint32_t>((ca | sa) | ((cb | sb) << (n - 8u)));
  }
#endif
  std::uint32_t m = 0;
  for (std::size_t i = 0; i < n; ++i)
    m |= std::uint32_t{must_escape(static_cast<unsigned char>(p[i]))} << i;
  return m;
}

/// Escape bits (as escape_mask16()) of the last @p rest (0 to 15) of the @p size bytes at @p data:
/// bit i for byte size - rest + i. Reads nothing outside the @p size bytes.
inline std::uint32_t tail_escape_mask(const char* data, std::size_t size, std::size_t rest) noexcept {
  if (rest == 0) return 0;
  if (size >= 16) return escape_mask16(data + size - 16u) >> (16u - rest);
  return escape_mask_short(data + size - rest, rest);
}

/// Number of bytes @p v takes on the wire once escaped (16 bytes at a time; the last bytes as the 16
/// that end the value, or two overlapping words, or one at a time in a value under 8 bytes).
inline std::size_t escaped_size(std::string_view v) noexcept {
  std::size_t n = v.size();
  const char* p = v.data();
  const char* const e = p + v.size();
  for (; e - p >= 16; p += 16)
    n += 2u * static_cast<std::size_t>(__builtin_popcount(escape_mask16(p)));
  if (v.size() >= 16 || e - p >= 8)
    return n + 2u * static_cast<std::size_t>(__builtin_popcount(
                        tail_escape_mask(v.data(), v.size(), static_cast<std::size_t>(e - p))));
  for (; p != e; ++p) n += must_escape(static_cast<unsigned char>(*p)) ? 2u : 0u;  // under 8 bytes
  return n;
}

/// Moves the @p len bytes at @p src to @p dst, which is either apart from them or at or before
/// @p src (they may overlap), like memmove but inline and 8 bytes at a time: the short moves of
/// unescaping do not pay for a call. Every 8-byte store lands at or before the source bytes still
/// to be read; the last 8 bytes are read first.
inline void move_left(unsigned char* dst, const unsigned char* src, std::size_t len) noexcept {
  if (len < 8) {
    for (std::size_t k = 0; k < len; ++k) dst[k] = src[k];
    return;
  }
  std::uint64_t last;
  std::memcpy(&last, src + len - 8u, 8);
  for (std::size_t k = 0; k + 8u <= len; k += 8) {
    std::uint64_t x;
    std::memcpy(&x, src + k, 8);
    std::memcpy(dst + k, &x, 8);
  }
  std::memcpy(dst + len - 8u, &last, 8);
}

/// Index of the lowest set bit of a non-zero @p m.
inline unsigned lowest_bit(std::uint64_t m) noexcept {
  return static_cast<unsigned>(__builtin_ctzll(static_cast<unsigned long long>(m)));
}

/// Copies the @p len bytes at @p src to @p dst for unescaping (the bytes of a param between two
/// escapes, or after its last): one 16-byte copy when the gap is at most 16 bytes and there are 16
/// bytes to read at @p src (@p src_room) and to write at @p dst (@p dst_room: the rest of the param,
/// whose bytes past the gap are written again or no longer part of it), else move_left().
inline void copy_within_param(unsigned char* dst, const unsigned char* src, std::size_t len,
                              std::size_t dst_room, std::size_t src_room) noexcept {
  if (len <= kChunk && dst_room >= kChunk && src_room >= kChunk) {
    unsigned char chunk[kChunk];
    std::memcpy(chunk, src, kChunk);
    std::memcpy(dst, chunk, kChunk);
    return;
  }
  move_left(dst, src, len);
}

/// Checks the escape that starts at byte @p i of the @p n param bytes at @p src (a special byte:
/// '%' or one that may not stand raw) and stores the byte it stands for in @p out. Returns ok,
/// non_printable_byte (not a '%') or bad_escape (not two upper-case hex digits, or a byte that
/// need not be escaped: not canonical).
inline Reason unescape_at(const unsigned char* src, std::size_t n, std::size_t i, unsigned char& out) noexcept {
  if (src[i] != '%') return Reason::non_printable_byte;
  if (n - i < 3) return Reason::bad_escape;
  const int hi = kHexTable.v[src[i + 1]];
  const int lo = kHexTable.v[src[i + 2]];
  const unsigned char b = static_cast<unsigned char>(hi * 16 + lo);
  if ((hi | lo) < 0 || !kEscapeBits.has(b)) return Reason::bad_escape;
  out = b;
  return Reason::ok;
}

/// The special bytes of a scanned region in order, from its per-block masks and the mask of blocks
/// that have any: each call returns the next one's offset, or kNone after the last.
struct SpecialBits {
  static constexpr std::size_t kNone = ~std::size_t{0};
  const std::uint64_t* specials;  ///< one mask per 64-byte block
  std::uint64_t blocks;           ///< the blocks not yet visited that have a special byte
  std::uint64_t m = 0;            ///< the specials of the block being visited, not yet returned
  std::size_t base = 0;           ///< that block's first offset

  std::size_t operator()() noexcept {
    while (m == 0) {
      if (blocks == 0) return kNone;
      const std::size_t k = lowest_bit(blocks);
      blocks &= blocks - 1u;
      m = specials[k];
      base = k * kBlock;
    }
    const std::size_t i = base + lowest_bit(m);
    m &= m - 1u;
    return i;
  }
};

/// Pass 1 of decode(): param j of a region whose ':'s are at @p at[0 .. colons) ends at at[j] and
/// the next begins after it; the last one ends at @p limit. Stores ends[0 .. colons] and
/// begins[0 .. colons]. With SSE2, 8 at a time: it reads at[] and writes ends and begins up to the
/// next multiple of 8 of @p colons (at[] has room for that; entries past @p colons mean nothing).
inline void param_bounds(const std::uint16_t* at, std::size_t colons, std::size_t limit, std::uint16_t* begins,
                         std::uint16_t* ends) noexcept {
#if defined(__SSE2__)
  static_assert(kMaxParams % 8u == 0, "begins and ends (kMaxParams each) take whole chunks of 8");
  __m128i carry = _mm_setzero_si128();  // lane 0: where the chunk's first param begins
  begins[0] = 0;
  for (std::size_t j = 0; j < colons; j += 8) {
    __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(at + j));
    // Opaque to the optimiser: GCC would otherwise split the plain copy to `ends` out of the loop
    // as a memcpy, inlined as `rep movsq`, whose start-up costs more than the whole loop.
    __asm__("" : "+x"(a));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(ends + j), a);
    const __m128i next = _mm_add_epi16(a, _mm_set1_epi16(1));  // where the param after each ':' begins
    _mm_storeu_si128(reinterpret_cast<__m128i*>(begins + j), _mm_or_si128(_mm_slli_si128(next, 2), carry));
    carry = _mm_srli_si128(next, 14);
  }
  if (colons != 0) begins[colons] = static_cast<std::uint16_t>(at[colons - 1u] + 1u);
  ends[colons] = static_cast<std::uint16_t>(limit);
#else
  begins[0] = 0;
  for (std::size_t j = 0; j < colons; ++j) {
    ends[j] = at[j];
    begins[j + 1u] = static_cast<std::uint16_t>(at[j] + 1u);
  }
  ends[colons] = static_cast<std::uint16_t>(limit);
#endif
}

/// The positions of the ':'s, in order: the set bits of the @p blocks masks at @p colons (bit i of
/// mask k is byte 64k + i), at most @p cap of them, into @p at (room for cap + 4). Returns how many
/// it wrote: cap means there may be more. Portable version, one bit at a time.
inline std::size_t colon_positions_generic(const std::uint64_t* colons, std::size_t blocks, std::size_t cap,
                                           std::uint16_t* at) noexcept {
  std::size_t seen = 0;
  if (cap == 0) return 0;
  for (std::size_t k = 0; k < blocks; ++k)
    for (std::uint64_t m = colons[k]; m != 0; m &= m - 1u) {
      at[seen++] = static_cast<std::uint16_t>(k * kBlock + lowest_bit(m));
      if (seen == cap) return seen;
    }
  return seen;
}

/// What decode()'s scan of the param region hands to its passes (with the per-block special masks).
struct Scan {
  std::size_t colons_seen = 0;      ///< ':' positions written (the cap given: there may be more)
  std::uint64_t special_blocks = 0; ///< bit k set where 64-byte block k has a special byte
};

/// The scan, portable version: copy_classify_generic(), then colon_positions_generic() and the
/// blocks with a special byte. Writes the specials of each block of the padded region to
/// @p specials and up to @p cap (at least 1) ':' positions to @p at (room for cap + 4).
inline Scan scan_generic(const unsigned char* src, std::size_t n, unsigned char* d, std::size_t cap,
                         std::uint16_t* at, std::uint64_t* specials) noexcept {
  std::uint64_t colons[kMaxDatagram / kBlock];
  copy_classify_generic(src, n, d, colons, specials);
  const std::size_t blocks = (((n + kChunk - 1u) & ~(kChunk - 1u)) + kBlock - 1u) / kBlock;
  Scan r;
  r.colons_seen = colon_positions_generic(colons, blocks, cap, at);
  for (std::size_t k = 0; k < blocks; ++k) r.special_blocks |= std::uint64_t{specials[k] != 0} << k;
  return r;
}

#if defined(__SSE2__)
/// The scan of a region of at most 64 bytes whose 16 bytes before src + n are readable
/// (copy_classify_small_sse2()); as scan_generic() otherwise.
inline Scan scan_small_sse2(const unsigned char* src, std::size_t n, unsigned char* d, std::size_t cap,
                            std::uint16_t* at, std::uint64_t* specials) noexcept {
  std::uint64_t colon = 0;
  copy_classify_small_sse2(src, n, d, colon, specials[0]);
  Scan r;
  r.colons_seen = colon_positions_generic(&colon, 1, cap, at);
  r.special_blocks = std::uint64_t{specials[0] != 0};
  return r;
}
#endif

#if defined(EV3PROTO_AVX2_DISPATCH)
/// Appends the ':' positions of one block's mask @p m (bit i = byte @p base + i) at at[seen], up to
/// @p cap in all; returns the new count. With POPCNT and TZCNT: the first four are written
/// unconditionally and the count advanced by the popcount, so a block costs no mispredicted exit.
__attribute__((target("avx2,bmi,popcnt"))) inline std::size_t append_positions_bmi(
    std::uint64_t m, std::size_t base, std::size_t seen, std::size_t cap, std::uint16_t* at) noexcept {
  const std::size_t cnt = static_cast<std::size_t>(__builtin_popcountll(m));
  if (seen + cnt >= cap) {  // the last block needed (or past it): exactly up to cap
    for (; seen < cap; m &= m - 1u) at[seen++] = static_cast<std::uint16_t>(base + lowest_bit(m));
    return seen;
  }
  for (std::size_t j = 0; j < 4; ++j, m &= m - 1u)  // bit 63 stands in for "none left"
    at[seen + j] = static_cast<std::uint16_t>(base + lowest_bit(m | (std::uint64_t{1} << 63)));
  for (std::size_t j = 4; j < cnt; ++j, m &= m - 1u) at[seen + j] = static_cast<std::uint16_t>(base + lowest_bit(m));
  return seen + cnt;
}

/// The scan with AVX2 (only called where the CPU has it, for n >= 64): each whole 64-byte block is
/// loaded once from @p src, stored to @p d, classified from the registers and its ':' positions taken
/// at once; the tail (under 64 bytes) by copy_classify_small_sse2(), whose 16 bytes before src + n
/// lie in the region. Nothing is padded. Reads nothing outside [src, src + n).
__attribute__((target("avx2,bmi,popcnt"))) inline Scan scan_avx2(const unsigned char* src, std::size_t n,
                                                                unsigned char* d, std::size_t cap,
                                                                std::uint16_t* at,
                                                                std::uint64_t* specials) noexcept {
  const __m256i k_colon = _mm256_set1_epi8(':');
  const __m256i k_percent = _mm256_set1_epi8('%');
  // As in classify_sse2(): adding 0x60 maps 0x20..0x7E onto -128..-34, every other byte above -34.
  const __m256i k_shift = _mm256_set1_epi8(0x60);
  const __m256i k_limit = _mm256_set1_epi8(-34);
  auto bits = [](__m256i m) __attribute__((target("avx2"))) {
    return std::uint64_t{static_cast<std::uint32_t>(_mm256_movemask_epi8(m))};
  };
  Scan r;
  std::size_t base = 0, k = 0;
  for (; n - base >= kBlock; base += kBlock, ++k) {
    const __m256i lo = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(src + base));
    const __m256i hi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(src + base + 32u));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(d + base), lo);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(d + base + 32u), hi);
    const __m256i slo = _mm256_or_si256(_mm256_cmpeq_epi8(lo, k_percent),
                                        _mm256_cmpgt_epi8(_mm256_add_epi8(lo, k_shift), k_limit));
    const __m256i shi = _mm256_or_si256(_mm256_cmpeq_epi8(hi, k_percent),
                                        _mm256_cmpgt_epi8(_mm256_add_epi8(hi, k_shift), k_limit));
    const std::uint64_t sp = bits(slo) | bits(shi) << 32;
    specials[k] = sp;
    r.special_blocks |= std::uint64_t{sp != 0} << k;
    r.colons_seen = append_positions_bmi(bits(_mm256_cmpeq_epi8(lo, k_colon)) | bits(_mm256_cmpeq_epi8(hi, k_colon)) << 32,
                                         base, r.colons_seen, cap, at);
  }
  if (base != n) {
    std::uint64_t colon = 0;
    copy_classify_small_sse2(src + base, n - base, d + base, colon, specials[k]);
    r.special_blocks |= std::uint64_t{specials[k] != 0} << k;
    r.colons_seen = append_positions_bmi(colon, base, r.colons_seen, cap, at);
  }
  return r;
}

/// Byte offsets 0..63, for scan_avx512()'s positions.
alignas(64) inline constexpr unsigned char kOffsets8[64] = {
    0,  1,  2,  3,  4,  5,  6,  7,  8,  9,  10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21,
    22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, 42, 43,
    44, 45, 46, 47, 48, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60, 61, 62, 63};

// GCC 12 warns inside its own _mm512_castsi512_si256() (an intentionally undefined upper half).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
/// The scan with AVX-512 (BW for whole 64-byte blocks, VBMI2 for the positions; only called where
/// the CPU has them, for n >= 64): each block is loaded once (the last one under a mask: nothing
/// outside [src, src + n) is read), stored to @p d (the last under the same mask), classified into
/// mask registers, and its ':' positions made by compressing the block's byte offsets under the ':'
/// mask, widening the first 32 to 16 bits and storing them whole (cap is at most 32, so no block
/// can contribute more): @p at needs room for cap + 32.
__attribute__((target("avx512f,avx512bw,avx512vbmi2,popcnt"))) inline Scan scan_avx512(
    const unsigned char* src, std::size_t n, unsigned char* d, std::size_t cap, std::uint16_t* at,
    std::uint64_t* specials) noexcept {
  const __m512i k_colon = _mm512_set1_epi8(':');
  const __m512i k_percent = _mm512_set1_epi8('%');
  const __m512i k_shift = _mm512_set1_epi8(0x60);  // as in classify_sse2()
  const __m512i k_limit = _mm512_set1_epi8(-34);
  const __m512i offsets = _mm512_load_si512(kOffsets8);
  std::size_t seen = 0;
  std::uint64_t special_blocks = 0;
  // One block at @p base (block k); @p in: its bytes inside the region (all 64 but in the last).
  auto block = [&](std::size_t base, std::size_t k, __mmask64 in, __m512i v)
                   __attribute__((target("avx512f,avx512bw,avx512vbmi2,popcnt"))) {
    const __mmask64 colon = _mm512_cmpeq_epi8_mask(v, k_colon);  // the bytes outside are 0: no ':'
    const __mmask64 special =
        (_mm512_cmpeq_epi8_mask(v, k_percent) | _mm512_cmpgt_epi8_mask(_mm512_add_epi8(v, k_shift), k_limit)) & in;
    specials[k] = _cvtmask64_u64(special);
    special_blocks |= std::uint64_t{_kortestz_mask64_u8(special, special) == 0} << k;
    const __m256i first = _mm512_castsi512_si256(_mm512_maskz_compress_epi8(colon, offsets));
    _mm512_storeu_si512(at + seen, _mm512_add_epi16(_mm512_cvtepu8_epi16(first),
                                                    _mm512_set1_epi16(static_cast<short>(base))));
    seen += static_cast<std::size_t>(__builtin_popcountll(_cvtmask64_u64(colon)));
    if (seen > cap) seen = cap;  // what is past cap is never read; the next store may overwrite it
  };
  std::size_t base = 0, k = 0;
  for (; n - base >= kBlock; base += kBlock, ++k) {
    const __m512i v = _mm512_loadu_si512(src + base);
    _mm512_storeu_si512(d + base, v);
    block(base, k, ~__mmask64{0}, v);
  }
  if (base != n) {  // the last bytes: loaded and stored under a mask
    const __mmask64 in = (__mmask64{1} << (n - base)) - 1u;
    const __m512i v = _mm512_maskz_loadu_epi8(in, src + base);
    _mm512_mask_storeu_epi8(d + base, in, v);
    block(base, k++, in, v);
  }
  Scan r;
  r.colons_seen = seen;
  r.special_blocks = special_blocks;
  return r;
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

/// True when the CPU has what scan_avx512() needs (asked on every call: loads and tests).
inline bool cpu_has_avx512_scan() noexcept {
  return __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vbmi2");
}

/// True when the CPU running this has AVX2 (asked on every call: a load and a test).
inline bool cpu_has_avx2() noexcept { return __builtin_cpu_supports("avx2"); }
#endif

/// decode()'s scan of the @p n param bytes at @p src: copies them to @p d, writes each 64-byte
/// block's special mask to @p specials and up to @p cap (at least 1) ':' positions to @p at (room for
/// cap + 32). @p tail_readable: the 16 bytes before src + n may be read (the datagram has 16 bytes).
/// Small regions take scan_small_sse2() (PING, reports), large ones scan_avx512() or scan_avx2()
/// where the CPU has them, the rest scan_generic(); all give the same result (tests: Classify.*).
inline Scan scan_params(const unsigned char* src, std::size_t n, bool tail_readable, unsigned char* d,
                        std::size_t cap, std::uint16_t* at, std::uint64_t* specials) noexcept {
#if defined(__SSE2__)
  if (n <= kBlock && tail_readable) return scan_small_sse2(src, n, d, cap, at, specials);
#else
  (void)tail_readable;
#endif
#if defined(EV3PROTO_AVX2_DISPATCH)
  if (n >= kBlock) {
    if (cpu_has_avx512_scan()) return scan_avx512(src, n, d, cap, at, specials);
    if (cpu_has_avx2()) return scan_avx2(src, n, d, cap, at, specials);
  }
#endif
  return scan_generic(src, n, d, cap, at, specials);
}

} // namespace detail

/// Number of bytes @p value takes as an escaped param on the wire (without its ':').
inline std::size_t escaped_size(std::string_view value) noexcept { return detail::escaped_size(value); }

/// Decodes one datagram into @p out, checking it from left to right as docs/protocol.md says.
/// Returns Reason::ok, or the first problem and its field index. On a rejection the content of
/// @p out is unspecified (but valid). Reads only [datagram.data(), datagram.data() + size()).
inline DecodeResult decode(std::string_view datagram, Message& out) noexcept {
  using detail::fail;
  const std::size_t len = datagram.size();
  if (len == 0) return fail(Reason::empty, kFieldSender);
  if (len > kMaxDatagram) return fail(Reason::too_long, kFieldSender);

  const char* p = datagram.data();
  const char* const e = p + len;

  // Header: four canonical numbers separated by ':'. Most datagrams have it, and the ':' after the
  // type, in their first 16 bytes: checked at once there; anything else (or any problem: it is then
  // named by the byte-at-a-time path) byte by byte.
  std::uint32_t hdr[4] = {0, 0, 0, 0};
  std::size_t params_at = 0;  // where param 0 starts; 0: no ':' follows the type (no params)
#if defined(__SSE2__)
  if (!(len >= detail::kChunk && detail::header_sse2(p, hdr, params_at)))
#endif
  {
    const DecodeResult h = detail::header_bytewise(p, len, hdr, params_at);
    if (!h.ok()) return h;
  }
  // A ':' after the type opens at least one (maybe empty) param.
  const bool has_params = params_at != 0;
  p += params_at;
  const MessageSpec* spec = find_spec(static_cast<std::uint8_t>(hdr[3]));
  if (spec == nullptr) return fail(Reason::unknown_type, kFieldType);
  out.sender = static_cast<std::uint16_t>(hdr[0]);
  out.receiver = static_cast<std::uint16_t>(hdr[1]);
  out.msgid = hdr[2];
  out.type = static_cast<MsgType>(hdr[3]);

  // Params. p is the first byte of param 0. A datagram that ends with ':' after the type carries one
  // empty param, so "p == e" alone does not mean "no params".
  //
  // The whole param region is copied into the message's buffer once, separators included, and
  // classified on the way (detail::scan_params()): the ':' positions (up to max_params of them) and,
  // per 64 bytes, a bit mask of the bytes that may not stand raw ("specials"). Three passes follow,
  // and the first problem in left-to-right order is reported (docs/protocol.md):
  //  1. the ':' bits give every param's bounds (a param without escapes is then done, in place,
  //     whatever its length); a ':' that would open param max_params is a too_many_params there;
  //  2. the special bits, in order: each must be a canonical %XX escape; a param that has one is
  //     unescaped in place (it only shrinks; its bytes between escapes move left once);
  //  3. params of a typed kind (numbers, states) are checked, only before the first problem so far.
  std::size_t count = 0;
  if (has_params) {
    const std::size_t max_params = spec->max_params < kMaxParams ? spec->max_params : kMaxParams;
    if (max_params == 0) return fail(Reason::too_many_params, kFieldParam0);
    const std::size_t n = static_cast<std::size_t>(e - p);
    unsigned char* const d = reinterpret_cast<unsigned char*>(out.data_);
    std::uint64_t specials[Message::kCapacity / detail::kBlock];
    std::uint16_t at[kMaxParams + 32];  // positions of the ':'s, in order (room: see scan_params())
    const detail::Scan scan = detail::scan_params(reinterpret_cast<const unsigned char*>(p), n,
                                                  len >= detail::kChunk, d, kMaxParams, at, specials);

    // Pass 1: bounds. The region examined ends at `limit`: n, or the ':' that opens param max_params.
    // (The scan takes up to kMaxParams positions, not max_params: then it need not wait for the row.)
    std::size_t colons_seen = scan.colons_seen < max_params ? scan.colons_seen : max_params;
    std::size_t limit = n;
    const bool too_many = colons_seen == max_params;
    if (too_many) limit = at[--colons_seen];
    detail::param_bounds(at, colons_seen, limit, out.begins_, out.ends_);
    count = colons_seen + 1u;

    // Pass 2: escapes, in order. A param with one is unescaped in place, all its escapes at once:
    // each %XX becomes its byte and the bytes between them move left. `bad` is the first param with a
    // bad byte (count if none). Bytes are read from the datagram (`src`), not from the copy just stored
    // (a load of bytes a wide store has just written may wait for it).
    const unsigned char* const src = reinterpret_cast<const unsigned char*>(p);
    std::size_t bad = count;
    Reason bad_reason = Reason::ok;
    detail::SpecialBits next{specials, scan.special_blocks};
    std::size_t i = next();      // the special byte looked at (kNone after the last)
    for (std::size_t cur = 0; i < limit;) {
      while (out.ends_[cur] < i) ++cur;  // the param holding byte i (ends_ of those before: shrunk)
      const std::size_t end = out.ends_[cur];
      std::size_t w = i;  // where the next unescaped byte of param cur goes
      for (;;) {
        const Reason why = detail::unescape_at(src, n, i, d[w]);
        if (why != Reason::ok) {
          bad = cur;
          bad_reason = why;
          break;
        }
        ++w;
        const std::size_t r = i + 3u;  // the hex digits are neither ':' nor special: no bit of theirs is set
        i = next();
        const std::size_t stop = i < end ? i : end;  // the plain bytes up to the next escape or the end
        detail::copy_within_param(d + w, src + r, stop - r, end - w, n - r);
        w += stop - r;
        if (i >= end) break;
      }
      if (bad != count) break;
      out.ends_[cur] = static_cast<std::uint16_t>(w);
    }

    // Pass 3: kinds, of the params before the first bad one.
    const detail::RowKinds& row = detail::kRowKinds[static_cast<std::size_t>(spec - kMessageTable)];
    const std::uint32_t checked = row.checked;
    for (std::uint32_t m = bad >= 32u ? checked : checked & ((std::uint32_t{1} << bad) - 1u); m != 0;
         m &= m - 1u) {
      const std::size_t k = static_cast<std::size_t>(__builtin_ctz(m));
      if (k >= count) break;
      const Reason kr = detail::check_kind(
          static_cast<ParamKind>((row.kinds >> (2u * k)) & 3u), std::string_view(out.data_ + out.begins_[k],
                                          static_cast<std::size_t>(out.ends_[k] - out.begins_[k])));
      if (kr != Reason::ok) return fail(kr, kFieldParam0 + k);
    }
    if (bad != count) return fail(bad_reason, kFieldParam0 + bad);
    if (too_many) return fail(Reason::too_many_params, kFieldParam0 + count);
  }
  out.count_ = static_cast<std::uint8_t>(count);
  if (count < spec->min_params) return fail(Reason::too_few_fields, kFieldParam0 + count);
  return DecodeResult{};
}

namespace detail {
/// encode_parts() and encode() share this: @p param(i) yields the value of param i.
template <typename ParamAt>
EncodeResult encode_impl(std::uint16_t sender, std::uint16_t receiver, std::uint32_t msgid,
                         std::uint8_t type, std::size_t count, ParamAt param, char* buf,
                         std::size_t cap) noexcept {
  auto refuse = [](Reason r, std::size_t field) noexcept {
    return EncodeResult{0, r, static_cast<std::uint8_t>(field)};
  };
  std::size_t size = decimal_digits(sender) + decimal_digits(receiver) +
                     decimal_digits(msgid) + decimal_digits(type) + 3u;
  for (std::size_t i = 0; i < count && size <= kMaxDatagram; ++i) size += 1u + escaped_size(param(i));
  if (size > kMaxDatagram) return refuse(Reason::too_long, kFieldSender);
  if (type == 0) return refuse(Reason::out_of_range, kFieldType);
  const MessageSpec* spec = find_spec(type);
  if (spec == nullptr) return refuse(Reason::unknown_type, kFieldType);
  for (std::size_t i = 0; i < count; ++i) {
    if (i >= kMaxParams || i >= spec->max_params) return refuse(Reason::too_many_params, kFieldParam0 + i);
    const Reason r = check_kind(spec->kind(i), param(i));
    if (r != Reason::ok) return refuse(r, kFieldParam0 + i);
  }
  if (count < spec->min_params) return refuse(Reason::too_few_fields, kFieldParam0 + count);
  if (size > cap || buf == nullptr) return refuse(Reason::too_long, kFieldSender);

  static constexpr char kHex[] = "0123456789ABCDEF";
  char* w = buf;
  w = write_decimal(w, sender);
  *w++ = ':';
  w = write_decimal(w, receiver);
  *w++ = ':';
  w = write_decimal(w, msgid);
  *w++ = ':';
  w = write_decimal(w, type);
  for (std::size_t i = 0; i < count; ++i) {
    *w++ = ':';
    const std::string_view value = param(i);
    const char* p = value.data();
    const char* const pe = p + value.size();
    // 16 bytes at a time: copied as they are, then the first byte to escape (if any) is rewritten.
    // Writing 16 bytes is in bounds: those input bytes take at least as many output bytes, all
    // within the computed size.
    while (pe - p >= 16) {
      std::memcpy(w, p, 16);
      const std::uint32_t m = escape_mask16(p);
      if (m == 0) {
        p += 16;
        w += 16;
        continue;
      }
      const unsigned plain = static_cast<unsigned>(__builtin_ctz(m));
      p += plain;
      w += plain;
      const unsigned char c = static_cast<unsigned char>(*p++);
      w[0] = '%';
      w[1] = kHex[c >> 4];
      w[2] = kHex[c & 0x0Fu];
      w += 3;
    }
    // The last 0 to 15 bytes: when none needs escaping (the usual case), one copy; a value under 8
    // bytes takes the byte loop (measured faster there).
    const std::size_t rest = static_cast<std::size_t>(pe - p);
    if (value.size() >= 16) {
      if (rest != 0 && escape_mask16(pe - 16) == 0) {
        // The 16 bytes ending at pe need no escape: those before p were written as they are, just
        // before w, so the 16 bytes ending the output can be written again from the input at once.
        std::memcpy(w + rest - 16, pe - 16, 16);
        w += rest;
        continue;
      }
    } else if (rest >= 8 && escape_mask_short(p, rest) == 0) {
      copy_short(reinterpret_cast<unsigned char*>(w), reinterpret_cast<const unsigned char*>(p), rest);
      w += rest;
      continue;
    }
    for (char ch : std::string_view(p, rest)) {
      const unsigned char c = static_cast<unsigned char>(ch);
      if (must_escape(c)) {
        w[0] = '%';
        w[1] = kHex[c >> 4];
        w[2] = kHex[c & 0x0Fu];
        w += 3;
      } else {
        *w++ = ch;
      }
    }
  }
  return EncodeResult{static_cast<std::size_t>(w - buf), Reason::ok, 0};
}
} // namespace detail

/// Encodes a message given as parts (header and @p count param values) in canonical form into
/// [buf, buf + cap). Refuses, with the reason and field decode() would report for the result, what
/// decode() would reject: result over 4096 bytes (too long, field 0), type 0 (out of range), an
/// undefined type (unknown type), more params than the type's max or than 32 (too many params), a
/// typed param that is not a valid value, fewer params than the type's min (too few fields). A result
/// that is valid but longer than @p cap is refused as too long (field 0). Writes nothing on refusal.
inline EncodeResult encode_parts(std::uint16_t sender, std::uint16_t receiver, std::uint32_t msgid,
                                 std::uint8_t type, const std::string_view* params, std::size_t count,
                                 char* buf, std::size_t cap) noexcept {
  return detail::encode_impl(sender, receiver, msgid, type, count,
                             [params](std::size_t i) noexcept { return params[i]; }, buf, cap);
}

/// Encodes @p m in canonical form into [buf, buf + cap); see encode_parts() for what is refused.
/// For every message encode() accepts, decode() of the result gives back @p m.
inline EncodeResult encode(const Message& m, char* buf, std::size_t cap) noexcept {
  return detail::encode_impl(m.sender, m.receiver, m.msgid, static_cast<std::uint8_t>(m.type), m.param_count(),
                             [&m](std::size_t i) noexcept { return m.param(i); }, buf, cap);
}

inline std::optional<std::uint32_t> Message::param_u32(std::size_t i) const noexcept {
  if (i >= count_) return std::nullopt;
  const std::string_view v = param(i);
  std::uint32_t n = 0;
  if (detail::parse_number(v.data(), v.data() + v.size(), 0xFFFFFFFFu, n) != Reason::ok) return std::nullopt;
  return n;
}

inline std::optional<std::uint16_t> Message::param_u16(std::size_t i) const noexcept {
  if (i >= count_) return std::nullopt;
  const std::string_view v = param(i);
  std::uint32_t n = 0;
  if (detail::parse_number(v.data(), v.data() + v.size(), 0xFFFFu, n) != Reason::ok) return std::nullopt;
  return static_cast<std::uint16_t>(n);
}

inline std::optional<AgentState> Message::param_state(std::size_t i) const noexcept {
  if (i >= count_) return std::nullopt;
  AgentState s = AgentState::IDLE;
  if (!parse_state(param(i), s)) return std::nullopt;
  return s;
}

} // namespace ev3proto
