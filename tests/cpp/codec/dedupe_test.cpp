// DedupeWindow: duplicates, FIFO eviction, wrap-around, payloads, and a randomized comparison with a
// simple reference model.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <random>
#include <utility>

#include "ev3proto/dedupe.hpp"

namespace {

using ev3proto::DedupeWindow;

TEST(Dedupe, DetectsDuplicates) {
  DedupeWindow<> w;
  EXPECT_EQ(w.capacity(), 50u);
  EXPECT_EQ(w.size(), 0u);
  EXPECT_TRUE(w.first_time(7, 12));
  EXPECT_FALSE(w.first_time(7, 12));
  EXPECT_FALSE(w.first_time(7, 12));
  EXPECT_TRUE(w.first_time(8, 12));   // same msgid, other sender
  EXPECT_TRUE(w.first_time(7, 13));
  EXPECT_TRUE(w.contains(7, 12));
  EXPECT_FALSE(w.contains(9, 12));
  EXPECT_EQ(w.size(), 3u);
  w.clear();
  EXPECT_EQ(w.size(), 0u);
  EXPECT_TRUE(w.first_time(7, 12));
}

TEST(Dedupe, FifoEvictionAtCapacity) {
  DedupeWindow<50> w;
  for (std::uint32_t id = 0; id < 50; ++id) ASSERT_TRUE(w.first_time(3, id));
  EXPECT_EQ(w.size(), 50u);
  for (std::uint32_t id = 0; id < 50; ++id) EXPECT_TRUE(w.contains(3, id));
  // A repeat does not refresh a key's age.
  EXPECT_FALSE(w.first_time(3, 0));
  ASSERT_TRUE(w.first_time(3, 50));  // evicts the oldest, id 0
  EXPECT_EQ(w.size(), 50u);
  EXPECT_FALSE(w.contains(3, 0));
  EXPECT_TRUE(w.contains(3, 1));
  EXPECT_TRUE(w.contains(3, 50));
  EXPECT_TRUE(w.first_time(3, 0));   // forgotten, so new again; evicts id 1
  EXPECT_FALSE(w.contains(3, 1));
  EXPECT_TRUE(w.contains(3, 2));
}

TEST(Dedupe, CapacityOne) {
  DedupeWindow<1> w;
  EXPECT_TRUE(w.first_time(1, 1));
  EXPECT_FALSE(w.first_time(1, 1));
  EXPECT_TRUE(w.first_time(1, 2));
  EXPECT_TRUE(w.first_time(1, 1));
  EXPECT_EQ(w.size(), 1u);
}

TEST(Dedupe, MsgidWrapAround) {
  DedupeWindow<> w;
  for (std::uint32_t k = 0; k < 10; ++k) ASSERT_TRUE(w.first_time(7, 4294967290u + k));  // ..95, 0..3
  EXPECT_TRUE(w.contains(7, 4294967295u));
  EXPECT_TRUE(w.contains(7, 0));
  EXPECT_TRUE(w.contains(7, 3));
  EXPECT_FALSE(w.first_time(7, 4294967295u));
  EXPECT_FALSE(w.first_time(7, 0));
  EXPECT_TRUE(w.first_time(7, 4));
  EXPECT_FALSE(w.contains(7, 4294967289u));
}

TEST(Dedupe, ManySenders) {
  DedupeWindow<50> w;
  // 50 senders, same msgid each: all distinct keys.
  for (std::uint16_t s = 0; s < 50; ++s) ASSERT_TRUE(w.first_time(static_cast<std::uint16_t>(60000 + s), 1));
  for (std::uint16_t s = 0; s < 50; ++s) EXPECT_TRUE(w.contains(static_cast<std::uint16_t>(60000 + s), 1));
  EXPECT_TRUE(w.first_time(65535, 4294967295u));
  EXPECT_FALSE(w.contains(60000, 1));
  EXPECT_TRUE(w.contains(65535, 4294967295u));
}

TEST(Dedupe, PayloadIsTheFirstAnswer) {
  struct Answer {
    std::uint8_t type = 0;
    std::uint32_t msgid = 0;
  };
  DedupeWindow<4, Answer> w;
  EXPECT_EQ(w.find(7, 12), nullptr);
  EXPECT_TRUE(w.insert(7, 12, Answer{3, 12}));
  const Answer* a = w.find(7, 12);
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->type, 3);
  EXPECT_EQ(a->msgid, 12u);
  // A second insert of the same key updates the payload but reports "not new".
  EXPECT_FALSE(w.insert(7, 12, Answer{4, 12}));
  EXPECT_EQ(w.find(7, 12)->type, 4);
  EXPECT_FALSE(w.first_time(7, 12));
  EXPECT_EQ(w.find(7, 12)->type, 4);  // first_time leaves a known key's payload alone
  if (Answer* m = w.find(7, 12)) m->type = 5;
  const auto& cw = w;
  EXPECT_EQ(cw.find(7, 12)->type, 5);
  EXPECT_TRUE(w.first_time(7, 13));
  EXPECT_EQ(w.find(7, 13)->type, 0);
}

TEST(Dedupe, SizesAndNoHeap) {
  static_assert(DedupeWindow<50>::kIndexSize == 128);
  static_assert(DedupeWindow<64>::kIndexSize == 128);
  static_assert(DedupeWindow<65>::kIndexSize == 256);
  static_assert(DedupeWindow<1>::kIndexSize == 2);
  static_assert(std::is_same<DedupeWindow<50>::Slot, std::uint16_t>::value);
  static_assert(std::is_same<DedupeWindow<70000>::Slot, std::uint32_t>::value);
  // Inline storage only: the object's size accounts for all of it.
  static_assert(sizeof(DedupeWindow<50>) >= 50 * 8 + 128 * 2);
  SUCCEED();
}

// Reference model: a deque of (key, payload), linear search, FIFO eviction at Size keys, or at
// @p limit keys when it is set (set_limit: one compiled size serving a smaller window).
template <std::size_t Size>
void against_model(std::uint32_t seed, int ops, std::uint32_t senders, std::uint32_t msgids,
                   std::size_t limit = 0) {
  DedupeWindow<Size, std::uint32_t> w;
  if (limit != 0) w.set_limit(limit);
  const std::size_t cap = limit != 0 ? limit : Size;
  ASSERT_EQ(w.limit(), cap);
  std::deque<std::pair<std::uint64_t, std::uint32_t>> model;
  std::mt19937 gen(seed);
  auto rng = [&gen] { return static_cast<std::uint32_t>(gen()); };
  for (int op = 0; op < ops; ++op) {
    const auto sender = static_cast<std::uint16_t>(rng() % senders);
    std::uint32_t msgid = rng() % msgids;
    if (rng() % 4 == 0) msgid = 4294967295u - msgid;  // exercise the top of the msgid range
    const std::uint64_t key = (std::uint64_t{sender} << 32) | msgid;
    auto it = std::find_if(model.begin(), model.end(), [&](const auto& e) { return e.first == key; });
    const std::uint32_t* got = w.find(sender, msgid);
    if (it == model.end()) {
      ASSERT_EQ(got, nullptr) << "op " << op;
    } else {
      ASSERT_NE(got, nullptr) << "op " << op;
      ASSERT_EQ(*got, it->second) << "op " << op;
    }
    const std::uint32_t value = static_cast<std::uint32_t>(op);
    const unsigned what = rng() % 3;
    if (what == 0) {  // insert
      const bool fresh = w.insert(sender, msgid, value);
      ASSERT_EQ(fresh, it == model.end()) << "op " << op;
      if (it != model.end()) {
        it->second = value;
      } else {
        if (model.size() == cap) model.pop_front();
        model.emplace_back(key, value);
      }
    } else if (what == 1) {  // first_time
      const bool fresh = w.first_time(sender, msgid);
      ASSERT_EQ(fresh, it == model.end()) << "op " << op;
      if (fresh) {
        if (model.size() == cap) model.pop_front();
        model.emplace_back(key, 0u);
      }
    }
    ASSERT_EQ(w.size(), model.size());
  }
  // Finally every key of the model is there with its payload.
  for (const auto& e : model) {
    const std::uint32_t* got = w.find(static_cast<std::uint16_t>(e.first >> 32), static_cast<std::uint32_t>(e.first));
    ASSERT_NE(got, nullptr);
    EXPECT_EQ(*got, e.second);
  }
}

TEST(Dedupe, RandomizedAgainstReferenceModel) {
  against_model<50>(1, 300000, 4, 80);     // keys often repeat, evictions constant
  against_model<50>(2, 100000, 65536, 4);  // many senders
  against_model<7>(3, 100000, 3, 8);       // small window, dense collisions
  against_model<64>(4, 100000, 2, 200);    // capacity = half the index
  against_model<1>(5, 20000, 2, 3);
  // One compiled window of 50 limited to the sizes the conformance runs use (ev3-agent --driver).
  for (std::size_t limit : {1u, 2u, 3u, 4u, 8u, 16u, 49u})
    against_model<50>(static_cast<std::uint32_t>(10 + limit), 30000, 3, 8 + 2 * static_cast<std::uint32_t>(limit), limit);
}

TEST(Dedupe, LimitEvictsAtTheLimit) {
  DedupeWindow<50> w;
  w.set_limit(3);
  EXPECT_EQ(w.limit(), 3u);
  EXPECT_EQ(w.capacity(), 50u);
  for (std::uint32_t id = 0; id < 4; ++id) EXPECT_TRUE(w.first_time(1, id));
  EXPECT_EQ(w.size(), 3u);
  EXPECT_FALSE(w.contains(1, 0));  // the oldest went at the fourth key
  EXPECT_TRUE(w.contains(1, 3));
  w.set_limit(0);  // 0: the capacity
  EXPECT_EQ(w.limit(), 50u);
  EXPECT_EQ(w.size(), 0u);  // set_limit forgets every key
  w.set_limit(51);
  EXPECT_EQ(w.limit(), 50u);
}

} // namespace
