// The wire format (docs/protocol.md): every field arrives bit for bit, in whichever form it travels —
// dense, sparse (mostly +0.0) or as an update of its previous message — and malformed frames are named.
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include <gtest/gtest.h>

#include "cosim/protocol.hpp"

namespace pr = cosim::protocol;

namespace {

pr::Message result(std::vector<double> values) {
  pr::Message m;
  m.header.type = pr::Type::kResult;
  m.header.window = 7;
  m.header.iteration = 2;
  m.header.value0 = 0.25;
  m.fields.push_back({"interface/force", std::move(values)});
  return m;
}

// The name frame of the first field as it travels.
std::string wireName(const zmq::multipart_t& frames) { return frames[1].to_string(); }

void expectBitwiseEqual(const std::vector<double>& a, const std::vector<double>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    ASSERT_EQ(std::bit_cast<std::uint64_t>(a[i]), std::bit_cast<std::uint64_t>(b[i])) << "index " << i;
}

}  // namespace

TEST(Protocol, DenseFieldsAndHeaderRoundTrip) {
  std::vector<double> v(300);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = std::sin(static_cast<double>(i)) * 1e3;
  pr::Message m = result(v);
  m.header.features = pr::kAllFeatures;
  auto frames = pr::encode(m, pr::kAllFeatures);
  EXPECT_EQ(wireName(frames), "interface/force");
  EXPECT_EQ(frames[2].size(), v.size() * sizeof(double));
  const pr::Message d = pr::decode(frames, "test");
  EXPECT_EQ(d.header.window, 7u);
  EXPECT_EQ(d.header.iteration, 2u);
  EXPECT_EQ(d.header.value0, 0.25);
  EXPECT_EQ(d.header.features, pr::kAllFeatures);
  expectBitwiseEqual(d.fields.at(0).data, v);
}

TEST(Protocol, MostlyZeroFieldTravelsSparseAndComesBackBitForBit) {
  std::vector<double> v(3000, 0.0);
  v[5] = 1.5;
  v[6] = -0.0;  // not +0.0: must keep its sign
  v[2999] = -2e-300;
  auto frames = pr::encode(result(v), pr::kSparseFields);
  EXPECT_EQ(wireName(frames), "sparse:interface/force");
  EXPECT_EQ(frames[2].size(), 8u + 3u * 16u);
  expectBitwiseEqual(pr::decode(frames, "test").fields.at(0).data, v);
  // Without the feature (a participant that did not offer it), the same field travels dense.
  auto dense = pr::encode(result(v), 0);
  EXPECT_EQ(wireName(dense), "interface/force");
  EXPECT_EQ(dense[2].size(), v.size() * sizeof(double));
}

TEST(Protocol, ChangedEntriesTravelAsAnUpdateOfThePreviousMessage) {
  pr::FieldMemory sent, received;
  std::vector<double> v(1000);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = 1.0 + static_cast<double>(i);
  auto first = pr::encode(result(v), pr::kAllFeatures, &sent);
  EXPECT_EQ(wireName(first), "interface/force");  // nothing to update yet
  expectBitwiseEqual(pr::decode(first, "test", &received).fields.at(0).data, v);
  v[3] = -4.0;
  v[400] = std::nextafter(v[400], 0.0);  // one ulp is a change
  auto second = pr::encode(result(v), pr::kAllFeatures, &sent);
  EXPECT_EQ(wireName(second), "update:interface/force");
  EXPECT_EQ(second[2].size(), 8u + 2u * 16u);
  expectBitwiseEqual(pr::decode(second, "test", &received).fields.at(0).data, v);
  expectBitwiseEqual(received.at("interface/force"), v);
  // Most entries changed: dense again, and still recorded on both sides.
  for (auto& x : v) x *= 2.0;
  auto third = pr::encode(result(v), pr::kAllFeatures, &sent);
  EXPECT_EQ(wireName(third), "interface/force");
  expectBitwiseEqual(pr::decode(third, "test", &received).fields.at(0).data, v);
  expectBitwiseEqual(sent.at("interface/force"), received.at("interface/force"));
}

TEST(Protocol, MalformedFieldsAreNamed) {
  auto expectError = [](zmq::multipart_t frames, const std::string& text, pr::FieldMemory* memory = nullptr) {
    try {
      pr::decode(frames, "participant \"dem\"", memory);
      ADD_FAILURE() << "no error, expected: " << text;
    } catch (const pr::ProtocolError& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  std::vector<double> v(100, 1.0);
  v[42] = std::numeric_limits<double>::quiet_NaN();
  expectError(pr::encode(result(v)), "non-finite value at index 42");
  std::vector<double> s(100, 0.0);
  s[77] = std::numeric_limits<double>::infinity();
  expectError(pr::encode(result(s), pr::kSparseFields), "non-finite value at index 77");
  // An update with nothing to update: the receiver never got the field.
  pr::FieldMemory sent;
  std::vector<double> u(100, 1.0);
  (void)pr::encode(result(u), pr::kFieldUpdates, &sent);
  u[1] = 2.0;
  pr::FieldMemory empty;
  expectError(pr::encode(result(u), pr::kFieldUpdates, &sent), "has no previous 100 values", &empty);
  // Indices out of order.
  std::vector<double> w(100, 0.0);
  w[10] = w[20] = 1.0;
  auto frames = pr::encode(result(w), pr::kSparseFields);
  auto* words = static_cast<std::uint64_t*>(frames[2].data());
  std::swap(words[1], words[2]);
  expectError(std::move(frames), "entry 1 has index 10");
}
