/// @file auth.hpp
/// @brief Signed datagrams (docs/protocol.md, "Signed datagrams"): a trailer with the key's id, a
///        per-sender counter and an HMAC-SHA-256 tag (libsodium) over everything before the tag; a
///        receiver's per-sender replay window. Pure computation: no I/O, no clock, no heap.
///
/// Signed form: `datagram LF keyid counter tag`, keyid 8, counter 16 and tag 32 upper-case hex
/// digits (57 bytes of trailer). A datagram never holds a raw LF (docs/protocol.md), so a receiver
/// tells a signed datagram from an unsigned one by its tail alone. The counter is `boot * 2^22 +
/// seq`: boot is the sender's start time in milliseconds (its clock, or one past the boot it last
/// used, whichever is later), seq counts the copies it signed since; a receiver keeps, per sender id,
/// the newest boot and a window of 64 seqs (the newest and 63 below), and refuses a counter it has
/// taken or that is older than the window or of an older boot.
///
/// Needs libsodium (`sodium_init()` once, before any Key is made; link -lsodium).
#pragma once

#include <sodium.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

namespace ev3proto::auth {

constexpr std::size_t kKeyBytes = 32;   ///< The fleet key.
constexpr std::size_t kTagBytes = 16;   ///< HMAC-SHA-256 truncated to 128 bits.
constexpr std::size_t kIdHex = 8;       ///< The key's id: 4 bytes of SHA-256(key), in hex.
constexpr std::size_t kCounterHex = 16; ///< The counter, 64 bits in hex.
/// The trailer: LF, key id, counter, tag.
constexpr std::size_t kTrailer = 1 + kIdHex + kCounterHex + 2 * kTagBytes;
constexpr unsigned kSeqBits = 22;       ///< Low bits of the counter: copies signed since boot.
constexpr std::uint64_t kSeqMask = (std::uint64_t{1} << kSeqBits) - 1;
constexpr std::uint64_t kMaxBoot = (std::uint64_t{1} << (64 - kSeqBits)) - 1;
constexpr unsigned kWindow = 64;        ///< Seqs a receiver remembers: the newest of a boot and 63 below.
/// The longest signed datagram: the longest datagram (docs/protocol.md) and its trailer.
constexpr std::size_t kMaxSigned = 4096 + kTrailer;

/// Why a datagram is refused (its drop counter: "auth:<name>").
enum class Verdict : std::uint8_t {
  ok,
  unsigned_,   ///< No trailer.
  malformed,   ///< A trailer that is not hex, or a sender field that is not a number.
  wrong_key,   ///< Signed with another key (its key id is not ours).
  bad_mac,     ///< Our key id, and the tag does not match: forged or altered.
  replay,      ///< A counter taken before, below the window, or of an older boot.
  table_full,  ///< A new sender and no room for it (more senders than the receiver's capacity).
};

/// The name of @p v for drop counters and logs ("bad_mac").
constexpr const char* verdict_name(Verdict v) noexcept {
  switch (v) {
    case Verdict::ok: return "ok";
    case Verdict::unsigned_: return "unsigned";
    case Verdict::malformed: return "malformed";
    case Verdict::wrong_key: return "wrong_key";
    case Verdict::bad_mac: return "bad_mac";
    case Verdict::replay: return "replay";
    case Verdict::table_full: return "table_full";
  }
  return "?";
}

namespace detail {
constexpr char kHex[] = "0123456789ABCDEF";
inline int hex_value(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}
/// Upper-case hex of @p n bytes of @p p into @p out (2n chars).
inline void to_hex(const unsigned char* p, std::size_t n, char* out) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    out[2 * i] = kHex[p[i] >> 4];
    out[2 * i + 1] = kHex[p[i] & 15];
  }
}
/// Reads 2n upper-case hex digits of @p s into @p out; false on any other byte.
inline bool from_hex(const char* s, std::size_t n, unsigned char* out) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    const int hi = hex_value(s[2 * i]), lo = hex_value(s[2 * i + 1]);
    if (hi < 0 || lo < 0) return false;
    out[i] = static_cast<unsigned char>(hi * 16 + lo);
  }
  return true;
}
}  // namespace detail

/// The fleet key and what is derived from it once: its id and HMAC-SHA-256's keyed state.
class Key {
 public:
  /// Reads the key file's text @p text: 64 hex digits (either case), one trailing newline allowed.
  /// nullptr, or what is wrong with it ("not 64 hex digits: 63 characters"). The text itself is
  /// never part of the message.
  static const char* parse(std::string_view text, Key& out) noexcept {
    if (!text.empty() && text.back() == '\n') text.remove_suffix(1);
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
    if (text.size() != 2 * kKeyBytes) return "is not 64 hex digits (a 32-byte key)";
    unsigned char k[kKeyBytes];
    for (std::size_t i = 0; i < kKeyBytes; ++i) {
      int d[2];
      for (int j = 0; j < 2; ++j) {
        char c = text[2 * i + static_cast<std::size_t>(j)];
        if (c >= 'a' && c <= 'f') c = static_cast<char>(c - 'a' + 'A');
        d[j] = detail::hex_value(c);
        if (d[j] < 0) {
          sodium_memzero(k, sizeof k);
          return "holds a character that is not a hex digit";
        }
      }
      k[i] = static_cast<unsigned char>(d[0] * 16 + d[1]);
    }
    out.set(k);
    sodium_memzero(k, sizeof k);
    return nullptr;
  }

  /// The key of the 32 bytes @p k.
  void set(const unsigned char* k) noexcept {
    unsigned char h[crypto_hash_sha256_BYTES];
    crypto_hash_sha256(h, k, kKeyBytes);
    detail::to_hex(h, kIdHex / 2, id_);
    crypto_auth_hmacsha256_init(&keyed_, k, kKeyBytes);
  }

  /// The key's id: 8 hex digits, the first 4 bytes of SHA-256(key); says which key signed, not
  /// the key.
  std::string_view id() const noexcept { return {id_, kIdHex}; }

  /// The first kTagBytes of HMAC-SHA-256(key, @p bytes followed by @p more) into @p tag.
  void tag(std::string_view bytes, unsigned char* tag, std::string_view more = {}) const noexcept {
    crypto_auth_hmacsha256_state st = keyed_;
    crypto_auth_hmacsha256_update(&st, reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size());
    if (!more.empty())
      crypto_auth_hmacsha256_update(&st, reinterpret_cast<const unsigned char*>(more.data()), more.size());
    unsigned char full[crypto_auth_hmacsha256_BYTES];
    crypto_auth_hmacsha256_final(&st, full);
    std::memcpy(tag, full, kTagBytes);
  }

  ~Key() { sodium_memzero(&keyed_, sizeof keyed_); }

 private:
  char id_[kIdHex] = {};
  crypto_auth_hmacsha256_state keyed_{};
};

/// The boot a sender signs with: its start time @p now_ms (its real-time clock, milliseconds since
/// 1970) or one past @p last_boot (the newest boot it used before, if it knows it), whichever is
/// later. Old traffic of a sender always has an older boot than its new traffic, so a receiver
/// that heard the new refuses the old.
constexpr std::uint64_t choose_boot(std::uint64_t now_ms, std::uint64_t last_boot = 0) noexcept {
  const std::uint64_t b = now_ms > last_boot ? now_ms : last_boot + 1;
  return b > kMaxBoot ? kMaxBoot : b;
}

/// A sender's signing state: its boot and the copies signed since.
class Signer {
 public:
  /// Signs with @p key from counter @p boot * 2^22 + @p seq on.
  Signer(const Key& key, std::uint64_t boot, std::uint64_t seq = 0) noexcept : key_(&key), boot_(boot), seq_(seq) {}

  /// Writes the kTrailer bytes that sign @p datagram into @p out, with the next counter.
  void seal(std::string_view datagram, char* out) noexcept {
    if (seq_ > kSeqMask) {  // 4 million copies in this boot: go on in the next millisecond's.
      ++boot_;
      seq_ = 0;
    }
    const std::uint64_t counter = (boot_ << kSeqBits) | seq_++;
    out[0] = '\n';
    std::memcpy(out + 1, key_->id().data(), kIdHex);
    for (std::size_t i = 0; i < kCounterHex; ++i)
      out[1 + kIdHex + i] = detail::kHex[(counter >> (4 * (kCounterHex - 1 - i))) & 15];
    // The tag covers the datagram and the trailer up to the tag.
    const std::size_t signed_tail = 1 + kIdHex + kCounterHex;
    unsigned char tag[kTagBytes];
    key_->tag(datagram, tag, std::string_view(out, signed_tail));
    detail::to_hex(tag, kTagBytes, out + signed_tail);
  }

  std::uint64_t boot() const noexcept { return boot_; }

 private:
  const Key* key_;
  std::uint64_t boot_;
  std::uint64_t seq_;
};

/// A receiver's check of signed datagrams: the key, and per sender id the newest boot and a window
/// of its last kWindow seqs, for up to @p Capacity senders (inline storage, no heap). With 65536,
/// every id has its slot (1.5 MiB) and the table is never full: the programs use that, so that no
/// replay of old traffic from many ids can fill it.
template <std::size_t Capacity>
class Verifier {
  static_assert(Capacity >= 1 && Capacity <= 65536, "Verifier capacity: 1..65536 senders");

 public:
  explicit Verifier(const Key& key) noexcept : key_(&key) {}

  /// Checks @p bytes; on ok, @p datagram is the datagram without its trailer and the counter is
  /// taken (a second time it is a replay). Nothing is taken unless the tag matches.
  Verdict open(std::string_view bytes, std::string_view& datagram) noexcept {
    if (bytes.size() < kTrailer || bytes[bytes.size() - kTrailer] != '\n') return Verdict::unsigned_;
    // Longer than the longest signed datagram: refused before its tag is computed (a stranger's
    // 64 KB datagrams would otherwise cost 16 times the hashing of the longest real one).
    if (bytes.size() > kMaxSigned) return Verdict::malformed;
    const char* t = bytes.data() + bytes.size() - kTrailer + 1;
    unsigned char counter_bytes[kCounterHex / 2];
    unsigned char got[kTagBytes];
    for (std::size_t i = 0; i < kIdHex; ++i)
      if (detail::hex_value(t[i]) < 0) return Verdict::malformed;
    if (!detail::from_hex(t + kIdHex, kCounterHex / 2, counter_bytes) ||
        !detail::from_hex(t + kIdHex + kCounterHex, kTagBytes, got))
      return Verdict::malformed;
    if (std::string_view(t, kIdHex) != key_->id()) return Verdict::wrong_key;
    unsigned char want[kTagBytes];
    key_->tag(bytes.substr(0, bytes.size() - 2 * kTagBytes), want);
    if (sodium_memcmp(got, want, kTagBytes) != 0) return Verdict::bad_mac;
    std::uint32_t sender = 0;
    if (!sender_of(bytes, sender)) return Verdict::malformed;
    std::uint64_t counter = 0;
    for (unsigned char b : counter_bytes) counter = (counter << 8) | b;
    const Verdict v = take(static_cast<std::uint16_t>(sender), counter);
    if (v == Verdict::ok) datagram = bytes.substr(0, bytes.size() - kTrailer);
    return v;
  }

  /// Senders known (each took room in the table).
  std::size_t senders() const noexcept { return used_; }

 private:
  struct Entry {
    std::uint64_t boot = 0;
    std::uint64_t bits = 0;  ///< Bit i: seq top - i taken.
    std::uint32_t top = 0;   ///< The newest seq taken in boot.
    std::uint16_t id = 0;
    bool used = false;
  };
  /// Every id has its own slot when the table can hold them all (65536: no probing, and never
  /// full); otherwise open addressing over twice the capacity, rounded up to a power of two.
  static constexpr bool kDirect = Capacity == 65536;
  static constexpr std::size_t kSlots = [] {
    if (kDirect) return std::size_t{65536};
    std::size_t n = 1;
    while (n < 2 * Capacity) n *= 2;
    return n;
  }();

  /// The sender field: a canonical decimal 0..65535 before the first ':'.
  static bool sender_of(std::string_view d, std::uint32_t& out) noexcept {
    std::size_t i = 0;
    out = 0;
    while (i < d.size() && d[i] >= '0' && d[i] <= '9' && i < 5) out = out * 10 + static_cast<std::uint32_t>(d[i++] - '0');
    return i > 0 && i < d.size() && d[i] == ':' && out <= 65535 && !(i > 1 && d[0] == '0');
  }

  Verdict take(std::uint16_t id, std::uint64_t counter) noexcept {
    std::size_t s = kDirect ? id : (static_cast<std::size_t>(id) * 40503u) & (kSlots - 1);
    while (!kDirect && slots_[s].used && slots_[s].id != id) s = (s + 1) & (kSlots - 1);
    Entry& e = slots_[s];
    const std::uint64_t boot = counter >> kSeqBits;
    const std::uint32_t seq = static_cast<std::uint32_t>(counter & kSeqMask);
    if (!e.used) {
      if (used_ == Capacity) return Verdict::table_full;
      ++used_;
      e.used = true;
      e.id = id;
      e.boot = boot;
      e.top = seq;
      e.bits = 1;
      return Verdict::ok;
    }
    if (boot < e.boot) return Verdict::replay;
    if (boot > e.boot) {
      e.boot = boot;
      e.top = seq;
      e.bits = 1;
      return Verdict::ok;
    }
    if (seq > e.top) {
      const std::uint32_t shift = seq - e.top;
      e.bits = shift >= kWindow ? 1 : (e.bits << shift) | 1;
      e.top = seq;
      return Verdict::ok;
    }
    const std::uint32_t back = e.top - seq;
    if (back >= kWindow) return Verdict::replay;
    const std::uint64_t bit = std::uint64_t{1} << back;
    if (e.bits & bit) return Verdict::replay;
    e.bits |= bit;
    return Verdict::ok;
  }

  const Key* key_;
  Entry slots_[kSlots]{};
  std::size_t used_ = 0;
};

}  // namespace ev3proto::auth
