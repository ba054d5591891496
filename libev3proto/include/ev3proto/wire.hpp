/// @file wire.hpp
/// @brief Wire format v2: decode and encode datagrams (docs/protocol.md is normative).
///
/// Header-only, C++17, no exceptions, no heap, no I/O, no mutable globals. decode() never reads
/// outside the datagram it is given; encode() never writes more than the caller's capacity.
///
/// One portable path, the same on the master (x86-64) and on the EV3 (ARMv5TE). decode() follows
/// the numbered list "Rejection: reasons and their order" of docs/protocol.md step by step, so it can
/// be read against it; the comments carry the step numbers.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string_view>
#include <type_traits>

#include "decimal.hpp"
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
  Message() noexcept {}  // NOLINT: deliberately leaves data_, begins_ and ends_ uninitialised (4 KiB)
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
  bool add_param_u32(std::uint32_t value) noexcept;

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

  std::uint8_t count_ = 0;            // number of params
  std::uint16_t begins_[kMaxParams];  // offset of param i's first byte in data_
  std::uint16_t ends_[kMaxParams];    // offset just past param i's last byte in data_
  char data_[kCapacity];              // the unescaped values (decode() leaves the separators between them)
};

static_assert(std::is_trivially_copyable<Message>::value, "Message must stay trivially copyable");

// ---- The rules of docs/protocol.md, one function each ----------------------------------------------

namespace detail {

/// True for a byte that a param must carry as a %XX escape: ':' '%' and bytes outside 0x20..0x7E.
/// Every other byte stands for itself ("Canonical form").
constexpr bool must_escape(unsigned char c) noexcept {
  return c < 0x20 || c > 0x7E || c == ':' || c == '%';
}

/// Value of an upper-case hex digit, or -1 (lower-case is not canonical and not accepted).
constexpr int upper_hex_value(unsigned char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// Checks that [p, e) is a canonical decimal number ("0", or a non-zero digit and more digits) no
/// greater than @p max. Returns ok, bad_number or out_of_range (bad_number wins: a field that is not
/// a number is not "too big"); stores the value in @p value when ok.
constexpr Reason parse_number(const char* p, const char* e, std::uint32_t max, std::uint32_t& value) noexcept {
  const std::size_t n = static_cast<std::size_t>(e - p);
  if (n == 0) return Reason::bad_number;
  if (n > 1 && *p == '0') return Reason::bad_number;
  std::uint64_t v = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (p[k] < '0' || p[k] > '9') return Reason::bad_number;
    if (v <= max) v = v * 10u + static_cast<unsigned>(p[k] - '0');  // once above max it stays above
  }
  if (v > max) return Reason::out_of_range;
  value = static_cast<std::uint32_t>(v);
  return Reason::ok;
}

/// Checks a param's unescaped value against its kind (table "Typed params"; text always passes).
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

/// Largest value of each header field, by field index (sender, receiver, msgid, type).
inline constexpr std::uint32_t kHeaderMax[4] = {0xFFFFu, 0xFFFFu, 0xFFFFFFFFu, 0xFFu};

/// A DecodeResult for a problem in field @p field.
constexpr DecodeResult fail(Reason r, std::size_t field) noexcept {
  return DecodeResult{r, static_cast<std::uint8_t>(field)};
}

/// The first @p c in [p, e), or e if there is none (memchr, which the C library makes fast).
inline const char* find_byte(const char* p, const char* e, char c) noexcept {
  const void* hit = std::memchr(p, c, static_cast<std::size_t>(e - p));
  return hit != nullptr ? static_cast<const char*>(hit) : e;
}

/// Copies [p, e) to @p dst and tells whether every byte lies within 0x20..0x7E (the smallest and the
/// largest do). A loop without an early exit or a branch, so that the compiler may copy and look at
/// many bytes at once.
inline bool copy_printable(const char* p, const char* e, char* dst) noexcept {
  unsigned char lo = 0xFF;
  unsigned char hi = 0x00;
  const std::size_t n = static_cast<std::size_t>(e - p);
  for (std::size_t k = 0; k < n; ++k) {
    const unsigned char c = static_cast<unsigned char>(p[k]);
    dst[k] = static_cast<char>(c);
    lo = c < lo ? c : lo;
    hi = c > hi ? c : hi;
  }
  return lo >= 0x20 && hi <= 0x7E;
}

/// The first byte of [p, e) outside 0x20..0x7E, or e if there is none.
inline const char* find_non_printable(const char* p, const char* e) noexcept {
  while (p != e && static_cast<unsigned char>(*p) >= 0x20 && static_cast<unsigned char>(*p) <= 0x7E) ++p;
  return p;
}

/// Unescapes the param [p, end) into @p dst, where its bytes already are (copied as they are), and
/// stores the value's size in @p size. The bytes before @p special (the param's first '%' or byte
/// outside 0x20..0x7E) stand for themselves and stay; from there on, left to right (docs/protocol.md
/// step 4): a '%' must open an escape of two upper-case hex digits, of a byte that must be escaped
/// (else bad escape), and becomes its byte; a byte outside 0x20..0x7E is a non-printable byte; any
/// other byte stands for itself.
inline Reason unescape(const char* p, const char* end, const char* special, char* dst, std::size_t& size) noexcept {
  char* w = dst + (special - p);
  for (const char* q = special; q != end; ++q) {
    const unsigned char c = static_cast<unsigned char>(*q);
    if (c == '%') {
      if (end - q < 3) return Reason::bad_escape;
      const int hi = upper_hex_value(static_cast<unsigned char>(q[1]));
      const int lo = upper_hex_value(static_cast<unsigned char>(q[2]));
      if (hi < 0 || lo < 0) return Reason::bad_escape;
      const unsigned char byte = static_cast<unsigned char>(hi * 16 + lo);
      if (!must_escape(byte)) return Reason::bad_escape;  // not canonical
      *w++ = static_cast<char>(byte);
      q += 2;
    } else if (c < 0x20 || c > 0x7E) {
      return Reason::non_printable_byte;
    } else {
      *w++ = static_cast<char>(c);
    }
  }
  size = static_cast<std::size_t>(w - dst);
  return Reason::ok;
}

} // namespace detail

// ---- Decode ------------------------------------------------------------------------------------------

/// Decodes one datagram into @p out, checking it from left to right as docs/protocol.md says.
/// Returns Reason::ok, or the first problem and its field index. On a rejection the content of
/// @p out is unspecified (but valid). Reads only [datagram.data(), datagram.data() + size()).
inline DecodeResult decode(std::string_view datagram, Message& out) noexcept {
  using detail::fail;
  // 1. and 2.: the length.
  if (datagram.empty()) return fail(Reason::empty, kFieldSender);
  if (datagram.size() > kMaxDatagram) return fail(Reason::too_long, kFieldSender);

  const char* p = datagram.data();
  const char* const e = p + datagram.size();

  // 3. The four header fields, in order, each up to the next ':' (or the end of the datagram).
  std::uint32_t header[4] = {0, 0, 0, 0};
  bool params_follow = false;  // a ':' after the type: at least one (maybe empty) param
  for (std::size_t k = 0; k < 4; ++k) {
    const char* q = p;
    while (q != e && *q != ':') ++q;
    const Reason r = detail::parse_number(p, q, detail::kHeaderMax[k], header[k]);
    if (r != Reason::ok) return fail(r, k);
    if (q == e && k < kFieldType) return fail(Reason::too_few_fields, k + 1u);  // field k+1 missing
    params_follow = q != e;
    p = params_follow ? q + 1 : e;
  }
  if (header[kFieldType] == 0) return fail(Reason::out_of_range, kFieldType);
  const MessageSpec* const spec = find_spec(static_cast<std::uint8_t>(header[kFieldType]));
  if (spec == nullptr) return fail(Reason::unknown_type, kFieldType);
  out.sender = static_cast<std::uint16_t>(header[kFieldSender]);
  out.receiver = static_cast<std::uint16_t>(header[kFieldReceiver]);
  out.msgid = header[kFieldMsgid];
  out.type = static_cast<MsgType>(header[kFieldType]);

  // 4. The params, in order. The whole param region is first copied into out.data_ as it is, and
  // checked for bytes outside 0x20..0x7E on the way: a param holding neither such a byte nor a '%' is
  // then its own value, in place. `bad` and `pct` point at the first such bytes in the datagram, so
  // that only a param holding one is looked at byte by byte (and unescaped over its copy). p is the
  // first byte of param i, `region` that of param 0.
  const char* const region = p;
  const char* const bad = detail::copy_printable(region, e, out.data_) ? e : detail::find_non_printable(region, e);
  const char* pct = detail::find_byte(region, e, '%');
  const char* special = pct < bad ? pct : bad;  // the first of them
  const std::size_t max_params = spec->max_params < kMaxParams ? spec->max_params : kMaxParams;
  // Params from this index on are text, whose value needs no check.
  const std::size_t typed = spec->kind(spec->declared) == ParamKind::text ? spec->declared : max_params;
  std::size_t count = 0;  // params accepted so far
  out.count_ = 0;
  while (params_follow) {
    const std::size_t i = count;
    const std::size_t field = kFieldParam0 + i;
    // When param i begins: too many params?
    if (i >= max_params) return fail(Reason::too_many_params, field);
    // Its bytes: up to the next ':' or the end of the datagram.
    const char* const end = detail::find_byte(p, e, ':');
    const std::size_t begin = static_cast<std::size_t>(p - region);
    std::size_t size = static_cast<std::size_t>(end - p);
    if (special < end) {
      const Reason r = detail::unescape(p, end, special, out.data_ + begin, size);
      if (r != Reason::ok) return fail(r, field);
      pct = detail::find_byte(end, e, '%');
      special = pct < bad ? pct : bad;
    }
    // Its value against its kind.
    if (i < typed) {
      const Reason r = detail::check_kind(spec->kind(i), std::string_view(out.data_ + begin, size));
      if (r != Reason::ok) return fail(r, field);
    }
    out.begins_[i] = static_cast<std::uint16_t>(begin);
    out.ends_[i] = static_cast<std::uint16_t>(begin + size);
    ++count;
    params_follow = end != e;  // stopped at a ':': another param begins after it
    p = params_follow ? end + 1 : e;
  }

  // 5. Fewer params than the type's min.
  if (count < spec->min_params) return fail(Reason::too_few_fields, kFieldParam0 + count);
  out.count_ = static_cast<std::uint8_t>(count);
  return DecodeResult{};
}

// ---- Encode ------------------------------------------------------------------------------------------

/// Number of bytes @p value takes as an escaped param on the wire (without its ':'): one per byte,
/// three per byte that must be escaped.
inline std::size_t escaped_size(std::string_view value) noexcept {
  std::size_t escapes = 0;
  for (const char c : value) escapes += detail::must_escape(static_cast<unsigned char>(c));
  return value.size() + 2u * escapes;
}

namespace detail {
/// encode_parts() and encode() share this: @p param(i) yields the value of param i.
/// Sizes the result and checks everything decode() would check first, then writes.
template <typename ParamAt>
EncodeResult encode_impl(std::uint16_t sender, std::uint16_t receiver, std::uint32_t msgid,
                         std::uint8_t type, std::size_t count, ParamAt param, char* buf,
                         std::size_t cap) noexcept {
  auto refuse = [](Reason r, std::size_t field) noexcept {
    return EncodeResult{0, r, static_cast<std::uint8_t>(field)};
  };
  // In decode()'s order: the length, the type, each param (too many, its kind), too few.
  std::size_t size = decimal_digits(sender) + decimal_digits(receiver) + decimal_digits(msgid) +
                     decimal_digits(type) + 3u;
  std::size_t escaped[kMaxParams];  // each param's escaped size (more than 32 params are refused)
  for (std::size_t i = 0; i < count && size <= kMaxDatagram; ++i) {
    const std::size_t n = escaped_size(param(i));
    if (i < kMaxParams) escaped[i] = n;
    size += 1u + n;
  }
  if (size > kMaxDatagram) return refuse(Reason::too_long, kFieldSender);
  if (type == 0) return refuse(Reason::out_of_range, kFieldType);
  const MessageSpec* const spec = find_spec(type);
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
    if (escaped[i] == value.size()) {  // nothing to escape: the value as it is
      std::memcpy(w, value.data(), value.size());
      w += value.size();
      continue;
    }
    for (const char ch : value) {
      const unsigned char c = static_cast<unsigned char>(ch);
      if (must_escape(c)) {  // "%XX", upper-case hex
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

/// Encodes the datagram @p inner (encoded already, not in [buf, buf + cap)) inside an envelope of
/// type @p type (RELAY, EPOCH_CMD) from @p sender to @p receiver with the inner datagram's @p msgid:
/// params (@p first in decimal: RELAY's agent, EPOCH_CMD's epoch; @p inner). The one envelope of the
/// agent's and the master's outboxes; refused as encode_parts().
inline EncodeResult encode_envelope(std::uint16_t sender, std::uint16_t receiver, std::uint32_t msgid,
                                    MsgType type, std::uint32_t first, std::string_view inner, char* buf,
                                    std::size_t cap) noexcept {
  char num[10];
  const std::string_view p[2] = {decimal(first, num), inner};
  return encode_parts(sender, receiver, msgid, static_cast<std::uint8_t>(type), p, 2, buf, cap);
}

/// Encodes @p m in canonical form into [buf, buf + cap); see encode_parts() for what is refused.
/// For every message encode() accepts, decode() of the result gives back @p m.
inline EncodeResult encode(const Message& m, char* buf, std::size_t cap) noexcept {
  return detail::encode_impl(m.sender, m.receiver, m.msgid, static_cast<std::uint8_t>(m.type), m.param_count(),
                             [&m](std::size_t i) noexcept { return m.param(i); }, buf, cap);
}

// ---- Message's typed accessors ---------------------------------------------------------------------

inline bool Message::add_param_u32(std::uint32_t value) noexcept {
  char digits[10];
  return add_param(decimal(value, digits));
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
