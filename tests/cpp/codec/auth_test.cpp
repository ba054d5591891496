// Signed datagrams (ev3proto/auth.hpp): the MAC against a published test vector, the key file's
// checks, a signer and a verifier together, and the replay window as transcripts
// (testdata/auth_*.txt).
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <ev3proto/auth.hpp>

#include "../datadriven/run.hpp"

namespace auth = ev3proto::auth;

namespace {

struct SodiumInit : ::testing::Environment {
  void SetUp() override { ASSERT_GE(sodium_init(), 0); }
};
const auto* const kInit = ::testing::AddGlobalTestEnvironment(new SodiumInit);

std::string hex(const unsigned char* p, std::size_t n) {
  std::string s(2 * n, '0');
  auth::detail::to_hex(p, n, s.data());
  return s;
}

auth::Key key_of(char fill) {
  auth::Key k;
  EXPECT_EQ(auth::Key::parse(std::string(64, fill), k), nullptr);
  return k;
}

}  // namespace

// RFC 4231, test case 2: libsodium's HMAC-SHA-256 is the published one.
TEST(Auth, HmacSha256MatchesRfc4231) {
  crypto_auth_hmacsha256_state st;
  const std::string key = "Jefe", data = "what do ya want for nothing?";
  crypto_auth_hmacsha256_init(&st, reinterpret_cast<const unsigned char*>(key.data()), key.size());
  crypto_auth_hmacsha256_update(&st, reinterpret_cast<const unsigned char*>(data.data()), data.size());
  unsigned char out[32];
  crypto_auth_hmacsha256_final(&st, out);
  EXPECT_EQ(hex(out, 32), "5BDCC146BF60754E6A042426089575C75A003F089D2739839DEC58B964EC3843");
}

// The tag is the first 16 bytes of HMAC-SHA-256 with the 32-byte key, over the datagram and the
// trailer up to the tag; the value was computed independently (Python's hmac module).
TEST(Auth, TrailerOfAKnownKeyAndCounter) {
  auth::Key k;
  ASSERT_EQ(auth::Key::parse("000102030405060708090a0b0c0d0e0f101112131415161718191A1B1C1D1E1F\n", k), nullptr);
  auth::Signer s(k, 1000);
  char t[auth::kTrailer];
  s.seal("1:7:5:9", t);
  EXPECT_EQ(std::string(t, auth::kTrailer),
            "\n630DCD2900000000FA000000" "849096EF452C8149E97A4E1B7A7E2636");
}

TEST(Auth, KeyFileText) {
  auth::Key k;
  EXPECT_EQ(auth::Key::parse(std::string(64, 'a'), k), nullptr);
  EXPECT_EQ(auth::Key::parse(std::string(64, 'A') + "\n", k), nullptr);
  EXPECT_EQ(auth::Key::parse(std::string(64, 'A') + "\r\n", k), nullptr);
  EXPECT_STREQ(auth::Key::parse(std::string(63, 'A'), k), "is not 64 hex digits (a 32-byte key)");
  EXPECT_STREQ(auth::Key::parse(std::string(66, 'A'), k), "is not 64 hex digits (a 32-byte key)");
  EXPECT_STREQ(auth::Key::parse(std::string(64, 'A') + "\n\n", k), "is not 64 hex digits (a 32-byte key)");
  EXPECT_STREQ(auth::Key::parse("", k), "is not 64 hex digits (a 32-byte key)");
  EXPECT_STREQ(auth::Key::parse(std::string(63, 'A') + "G", k), "holds a character that is not a hex digit");
}

TEST(Auth, BootIsTheClockOrOnePastTheLast) {
  EXPECT_EQ(auth::choose_boot(5000), 5000u);
  EXPECT_EQ(auth::choose_boot(5000, 4000), 5000u);
  EXPECT_EQ(auth::choose_boot(5000, 5000), 5001u);
  EXPECT_EQ(auth::choose_boot(3, 9000), 9001u);  // a clock set back
  EXPECT_EQ(auth::choose_boot(~std::uint64_t{0}), auth::kMaxBoot);
}

// Every copy the signer seals is taken once, in any order within the window.
TEST(Auth, SignerAndVerifierRoundTrip) {
  const auth::Key k = key_of('5');
  auth::Signer s(k, 123456);
  auto v = std::make_unique<auth::Verifier<8>>(k);
  std::vector<std::string> sent;
  for (int i = 0; i < 40; ++i) {
    std::string d = "7:1:" + std::to_string(i) + ":5:WORKING";
    char t[auth::kTrailer];
    s.seal(d, t);
    sent.push_back(d + std::string(t, auth::kTrailer));
  }
  for (int i = 39; i >= 0; --i) {  // reversed: 40 < the window of 64
    std::string_view out;
    ASSERT_EQ(v->open(sent[static_cast<std::size_t>(i)], out), auth::Verdict::ok) << i;
    EXPECT_EQ(out, "7:1:" + std::to_string(i) + ":5:WORKING");
  }
  for (const auto& d : sent) {
    std::string_view out;
    EXPECT_EQ(v->open(d, out), auth::Verdict::replay);
  }
}

// Every single bit flipped anywhere in a signed datagram is refused, and leaves the window as it was.
TEST(Auth, EveryBitFlipIsRefused) {
  const auth::Key k = key_of('7');
  auth::Signer s(k, 99);
  auth::Verifier<4> v(k);
  const std::string d = "1:7:12:10";
  char t[auth::kTrailer];
  s.seal(d, t);
  const std::string good = d + std::string(t, auth::kTrailer);
  for (std::size_t i = 0; i < good.size(); ++i)
    for (int b = 0; b < 8; ++b) {
      std::string bad = good;
      bad[i] = static_cast<char>(bad[i] ^ (1 << b));
      std::string_view out;
      EXPECT_NE(v.open(bad, out), auth::Verdict::ok) << "byte " << i << " bit " << b;
    }
  std::string_view out;
  EXPECT_EQ(v.open(good, out), auth::Verdict::ok);
  EXPECT_EQ(v.senders(), 1u);
}

// Longer than any signed datagram (4096 + 57 bytes): refused as malformed before its tag is
// computed, even when the tag is right; the longest one is taken.
TEST(Auth, OverLongIsRefusedBeforeTheTag) {
  const auth::Key k = key_of('3');
  auth::Signer s(k, 5);
  auth::Verifier<4> v(k);
  char t[auth::kTrailer];
  const std::string longest = "1:7:9:7:" + std::string(4096 - 8, 'a');
  s.seal(longest, t);
  std::string_view out;
  EXPECT_EQ(v.open(longest + std::string(t, auth::kTrailer), out), auth::Verdict::ok);
  const std::string over = longest + "a";
  s.seal(over, t);
  EXPECT_EQ(v.open(over + std::string(t, auth::kTrailer), out), auth::Verdict::malformed);
}

TEST(Auth, SequenceOverflowGoesOnInTheNextBoot) {
  const auth::Key k = key_of('1');
  auth::Signer s(k, 10, auth::kSeqMask);
  char t[auth::kTrailer];
  s.seal("1:2:3:8", t);
  EXPECT_EQ(s.boot(), 10u);
  EXPECT_EQ(std::string(t + 1 + auth::kIdHex, auth::kCounterHex), "0000000002BFFFFF");
  s.seal("1:2:3:8", t);
  EXPECT_EQ(s.boot(), 11u);
  EXPECT_EQ(std::string(t + 1 + auth::kIdHex, auth::kCounterHex), "0000000002C00000");
}

// ---- Transcripts: a receiver and datagrams built with any key and counter.
//
//   receiver key=K cap=N        a new verifier with key K (one hex digit, repeated 64 times)
//   recv key=K boot=B seq=S [flip=I] DATAGRAM
//                               DATAGRAM signed with key K and counter B*2^22+S (byte I of the
//                               result flipped: its lowest bit), given to the receiver
//   recv raw TEXT               TEXT as it is (\n for LF)
// Output: `ok DATAGRAM` or `drop REASON`; `senders N` after `receiver`.
namespace {

class AuthDriver {
 public:
  std::vector<std::string> run(const std::vector<std::string>& input) {
    std::vector<std::string> out;
    for (const auto& line : input) out.push_back(step(line));
    return out;
  }

 private:
  static std::map<std::string, std::string> words(std::istringstream& in, std::string& rest) {
    std::map<std::string, std::string> kv;
    std::string w;
    while (in >> w) {
      const auto eq = w.find('=');
      if (eq == std::string::npos) {
        std::getline(in, rest);
        rest = w + rest;
        break;
      }
      kv[w.substr(0, eq)] = w.substr(eq + 1);
    }
    return kv;
  }

  std::string step(const std::string& line) {
    std::istringstream in(line);
    std::string cmd;
    in >> cmd;
    if (cmd == "receiver") {
      std::string rest;
      auto kv = words(in, rest);
      key_ = std::make_unique<auth::Key>(key_of(kv["key"].at(0)));
      cap_ = std::stoul(kv["cap"]);
      v4_ = std::make_unique<auth::Verifier<4>>(*key_);
      v64_ = std::make_unique<auth::Verifier<64>>(*key_);
      return "ok";
    }
    if (cmd == "senders") return "senders " + std::to_string(cap_ == 4 ? v4_->senders() : v64_->senders());
    if (cmd != "recv") return "error: unknown command " + cmd;
    std::string bytes;
    std::string first;
    in >> first;
    if (first == "raw") {
      std::getline(in, bytes);
      bytes = bytes.substr(1);
      for (std::size_t p; (p = bytes.find("\\n")) != std::string::npos;) bytes.replace(p, 2, "\n");
    } else {
      std::istringstream again(line.substr(line.find(first)));
      std::string d;
      auto kv = words(again, d);
      const auth::Key k = key_of(kv["key"].at(0));
      auth::Signer s(k, std::stoull(kv["boot"]), std::stoull(kv["seq"]));
      char t[auth::kTrailer];
      s.seal(d, t);
      bytes = d + std::string(t, auth::kTrailer);
      if (kv.count("flip")) bytes[std::stoul(kv["flip"])] ^= 1;
    }
    std::string_view got;
    const auth::Verdict r = cap_ == 4 ? v4_->open(bytes, got) : v64_->open(bytes, got);
    if (r == auth::Verdict::ok) return "ok " + std::string(got);
    return std::string("drop ") + auth::verdict_name(r);
  }

  std::unique_ptr<auth::Key> key_;
  std::size_t cap_ = 4;
  std::unique_ptr<auth::Verifier<4>> v4_;
  std::unique_ptr<auth::Verifier<64>> v64_;
};

class AuthTranscript : public ::testing::TestWithParam<std::string> {};
TEST_P(AuthTranscript, Matches) { datadriven::run_file<AuthDriver>(GetParam()); }
INSTANTIATE_TEST_SUITE_P(Testdata, AuthTranscript,
                         ::testing::ValuesIn(datadriven::files_with_prefix(EV3_TESTDATA, "auth_")),
                         datadriven::test_name);

}  // namespace
