// libFuzzer target: the receiver's check of signed datagrams (ev3proto/auth.hpp) against a plain
// model of docs/protocol.md "Signed datagrams". The input is a program of steps: sign a datagram
// with the fleet key and any counter, take bytes as they are, flip a bit of the last signed one,
// send it again. Each result goes to one Verifier (4 senders); the model, written from the doc with
// libsodium's one-shot HMAC and SHA-256 (not with auth::Key), says what the verdict must be, reason
// and all: genuine tags only, each counter once, none older than the window or of an older boot,
// no fifth sender, senders that are canonical numbers. Anything else traps. Also linked with
// replay_main.cpp (the corpus).
#include <cstddef>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <string_view>

#include "ev3proto/auth.hpp"
#include "fuzz_input.hpp"

namespace auth = ev3proto::auth;

namespace {

using fuzzin::Reader;
using fuzzin::violation;

struct SenderModel {
  std::uint64_t boot = 0;
  std::uint64_t top = 0;
  std::set<std::uint64_t> seqs;
};

/// The model: per sender id, the newest boot and the seqs taken in it.
struct Model {
  std::map<std::uint32_t, SenderModel> senders;
  auth::Verdict window(std::uint32_t id, std::uint64_t counter) const {
    const std::uint64_t boot = counter >> auth::kSeqBits, seq = counter & auth::kSeqMask;
    const auto it = senders.find(id);
    if (it == senders.end()) return senders.size() < 4 ? auth::Verdict::ok : auth::Verdict::table_full;
    const SenderModel& s = it->second;
    if (boot != s.boot) return boot > s.boot ? auth::Verdict::ok : auth::Verdict::replay;
    if (seq > s.top) return auth::Verdict::ok;
    return s.top - seq < auth::kWindow && s.seqs.count(seq) == 0 ? auth::Verdict::ok : auth::Verdict::replay;
  }
  void take(std::uint32_t id, std::uint64_t counter) {
    const std::uint64_t boot = counter >> auth::kSeqBits, seq = counter & auth::kSeqMask;
    SenderModel& s = senders[id];
    if (s.seqs.empty() || boot > s.boot) {
      s = SenderModel{boot, seq, {seq}};
      return;
    }
    s.seqs.insert(seq);
    if (seq > s.top) s.top = seq;
  }
};

/// The sender field as docs/protocol.md defines a number: canonical decimal 0..65535, then ':'.
/// (This file's helpers are written from the doc on purpose, not taken from the codec or auth.hpp:
/// the model must not share the code it checks.)
bool sender_of(std::string_view d, std::uint32_t& id) {
  const std::size_t colon = d.find(':');
  if (colon == std::string_view::npos || colon == 0 || colon > 5 || (colon > 1 && d[0] == '0')) return false;
  id = 0;
  for (std::size_t i = 0; i < colon; ++i) {
    if (d[i] < '0' || d[i] > '9') return false;
    id = id * 10 + static_cast<std::uint32_t>(d[i] - '0');
  }
  return id <= 65535;
}

/// The fleet key's bytes (the key file's 64 'C's) and what follows from them, computed here with
/// libsodium's one-shot functions, not with auth::Key.
const unsigned char* raw_key() {
  static unsigned char k[32];
  for (unsigned char& c : k) c = 0xCC;
  return k;
}
std::string upper_hex(const unsigned char* p, std::size_t n) {
  static const char* d = "0123456789ABCDEF";
  std::string s;
  for (std::size_t i = 0; i < n; ++i) s += {d[p[i] >> 4], d[p[i] & 15]};
  return s;
}
bool upper_hex_digits(std::string_view s) {
  for (char c : s)
    if (!((c >= '0' && c <= '9') || (c >= 'A' && c <= 'F'))) return false;
  return true;
}

/// What docs/protocol.md "Signed datagrams" says a receiver with the fleet key does with @p b, in
/// its order: no trailer, over-long, not hex, another key's id, a tag that does not match, a sender
/// that is not a number, then the window. @p id and @p counter: the sender and counter when the
/// window decides.
auth::Verdict expected(std::string_view b, std::uint32_t& id, std::uint64_t& counter, const Model& model) {
  if (b.size() < 57 || b[b.size() - 57] != '\n') return auth::Verdict::unsigned_;
  if (b.size() > 4096 + 57) return auth::Verdict::malformed;
  const std::string_view t = b.substr(b.size() - 56);
  if (!upper_hex_digits(t)) return auth::Verdict::malformed;
  unsigned char h[32];
  crypto_hash_sha256(h, raw_key(), 32);
  if (t.substr(0, 8) != upper_hex(h, 4)) return auth::Verdict::wrong_key;
  unsigned char mac[32];
  crypto_auth_hmacsha256(mac, reinterpret_cast<const unsigned char*>(b.data()), b.size() - 32, raw_key());
  if (t.substr(24) != upper_hex(mac, 16)) return auth::Verdict::bad_mac;
  if (!sender_of(b, id)) return auth::Verdict::malformed;
  counter = std::stoull(std::string(t.substr(8, 16)), nullptr, 16);
  return model.window(id, counter);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static auth::Key key = [] {
    auth::Key k;
    if (sodium_init() < 0 || auth::Key::parse(std::string(64, 'C'), k) != nullptr) violation("the key");
    return k;
  }();
  static auth::Verifier<4>* v = nullptr;  // one per input, off the stack (4 senders, 8 slots)
  delete v;
  v = new auth::Verifier<4>(key);
  Model model;
  Reader in{data, size};
  std::string last;
  while (in.n > 0) {
    std::string bytes;
    switch (in.byte() % 4) {
      case 0: {  // sign "S:1:M:5:IDLE" with any boot and seq, S a sender id or not quite one
        static const char* const kSenders[] = {"0", "1", "2", "3", "4", "5", "01", "65535", "65536", "x", "123456"};
        // Each input byte read into a local, in order: the order of a call's arguments is the
        // compiler's (a finding must replay the same under clang and gcc).
        const char* const sender = kSenders[in.byte() % 11];
        const unsigned msgid = in.byte();
        const std::string d = std::string(sender) + ":1:" + std::to_string(msgid) + ":5:IDLE";
        const unsigned boot = 1 + in.byte() % 3;
        const unsigned seq = in.u16() % 300;
        auth::Signer s(key, boot, seq);
        char t[auth::kTrailer];
        s.seal(d, t);
        bytes = last = d + std::string(t, auth::kTrailer);
        break;
      }
      case 1: {  // bytes as they are
        const std::size_t len = in.u16() % 200;
        for (std::size_t i = 0; i < len && in.n > 0; ++i) bytes.push_back(static_cast<char>(in.byte()));
        break;
      }
      case 2:  // the last signed one with a bit flipped
        bytes = last;
        if (!bytes.empty()) bytes[in.u16() % bytes.size()] ^= static_cast<char>(1 << (in.byte() % 8));
        break;
      default:  // the last signed one again
        bytes = last;
        break;
    }
    std::uint32_t id = 0;
    std::uint64_t counter = 0;
    const auth::Verdict want = expected(bytes, id, counter, model);
    std::string_view out;
    const auth::Verdict r = v->open(bytes, out);
    if (r != want) violation(auth::verdict_name(want));  // the verdict the model expected
    if (want == auth::Verdict::ok) {
      if (out != std::string_view(bytes).substr(0, bytes.size() - auth::kTrailer)) violation("the datagram taken");
      model.take(id, counter);
    }
    if (v->senders() != model.senders.size()) violation("the count of senders");
  }
  return 0;
}
