#include "cosim/protocol.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>

#include <fmt/format.h>

namespace cosim::protocol {

const char* toString(Type t) {
  switch (t) {
    case Type::kHello: return "HELLO";
    case Type::kWelcome: return "WELCOME";
    case Type::kAdvance: return "ADVANCE";
    case Type::kResult: return "RESULT";
    case Type::kFinalize: return "FINALIZE";
    case Type::kError: return "ERROR";
    case Type::kHeartbeat: return "HEARTBEAT";
    case Type::kBye: return "BYE";
  }
  return "?";
}

const Field* Message::field(const std::string& name) const {
  for (const auto& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

namespace {
template <class T>
void put(unsigned char* buf, std::size_t offset, T v) {
  std::memcpy(buf + offset, &v, sizeof(T));
}
template <class T>
T get(const unsigned char* buf, std::size_t offset) {
  T v;
  std::memcpy(&v, buf + offset, sizeof(T));
  return v;
}

constexpr const char* kSparsePrefix = "sparse:";
constexpr const char* kUpdatePrefix = "update:";

// Hands a vector's buffer to ZeroMQ, which frees it once the frame is sent.
zmq::message_t adopt(std::vector<double>&& values) {
  if (values.size() < 8) return zmq::message_t(values.data(), values.size() * sizeof(double));
  auto* owned = new std::vector<double>(std::move(values));
  return zmq::message_t(owned->data(), owned->size() * sizeof(double),
                        [](void*, void* hint) { delete static_cast<std::vector<double>*>(hint); }, owned);
}

std::uint64_t bits(double x) {
  std::uint64_t u;
  std::memcpy(&u, &x, sizeof u);
  return u;
}

// The entries of v whose bits differ from base (+0.0 everywhere when base is null), if fewer than a
// quarter of them: the frame of a sparse or update field (docs/protocol.md: u64 length, u64 indices,
// f64 values). Empty when the dense frame is the cheaper one. Comparing bits, not values, gives the
// receiver every bit back (-0.0 stays -0.0).
std::vector<std::uint64_t> entriesAgainst(const std::vector<double>& v, const double* base) {
  const std::size_t n = v.size(), limit = n / 4;
  if (n < 16) return {};
  std::vector<std::uint64_t> index;
  index.reserve(limit);
  for (std::size_t i = 0; i < n; ++i)
    if (bits(v[i]) != (base ? bits(base[i]) : 0)) {
      if (index.size() == limit) return {};
      index.push_back(i);
    }
  std::vector<std::uint64_t> out(1 + 2 * index.size());
  out[0] = n;
  std::copy(index.begin(), index.end(), out.begin() + 1);
  for (std::size_t k = 0; k < index.size(); ++k) out[1 + index.size() + k] = bits(v[index[k]]);
  return out;
}

// Copies `count` float64 from `src` to `dst`; the index of the first non-finite value, or count.
// One pass with an integer test of the exponent bits, which the compiler vectorises.
std::size_t copyFinite(const unsigned char* src, std::size_t count, double* dst) {
  if (count == 0) return 0;  // an empty field (HELLO's name: and token:): dst may be null, memcpy must not see it
  std::memcpy(dst, src, count * sizeof(double));
  std::uint64_t bad = 0;
  for (std::size_t k = 0; k < count; ++k) {
    std::uint64_t u;
    std::memcpy(&u, dst + k, sizeof u);
    bad |= static_cast<std::uint64_t>((u & 0x7ff0000000000000ull) == 0x7ff0000000000000ull);
  }
  if (!bad) return count;
  for (std::size_t k = 0; k < count; ++k)
    if (!std::isfinite(dst[k])) return k;
  return count;
}

}  // namespace

zmq::multipart_t encode(Message m, std::uint32_t features, FieldMemory* sent) {
  unsigned char h[kHeaderSize] = {};
  put(h, 0, kMagic);
  put(h, 4, kVersion);
  put(h, 6, static_cast<std::uint16_t>(m.header.type));
  put(h, 8, m.header.window);
  put(h, 16, m.header.iteration);
  put(h, 20, m.header.flags);
  put(h, 24, m.header.time);
  put(h, 32, m.header.dt);
  put(h, 40, m.header.value0);
  put(h, 48, m.header.value1);
  put(h, 56, static_cast<std::uint32_t>(m.header.type == Type::kError ? 0 : m.fields.size()));
  put(h, 60, m.header.features);
  zmq::multipart_t out;
  out.addmem(h, kHeaderSize);
  if (m.header.type == Type::kError) {
    out.addstr(m.text);
    return out;
  }
  const bool remember = sent && (features & kFieldUpdates);
  for (auto& f : m.fields) {
    std::vector<std::uint64_t> entries;
    const char* prefix = "";
    if (remember) {
      const auto last = sent->find(f.name);
      if (last != sent->end() && last->second.size() == f.data.size()) {
        entries = entriesAgainst(f.data, last->second.data());
        prefix = kUpdatePrefix;
      }
    }
    if (features & kSparseFields) {
      auto zeros = entriesAgainst(f.data, nullptr);
      if (!zeros.empty() && (entries.empty() || zeros.size() < entries.size())) {
        entries = std::move(zeros);
        prefix = kSparsePrefix;
      }
    }
    if (remember) (*sent)[f.name] = f.data;
    if (!entries.empty()) {
      out.addstr(prefix + f.name);
      out.addmem(entries.data(), entries.size() * sizeof(std::uint64_t));
    } else {
      out.addstr(f.name);
      out.add(adopt(std::move(f.data)));
    }
  }
  return out;
}

Message decode(zmq::multipart_t& frames, const std::string& from, FieldMemory* received) {
  if (frames.empty()) throw ProtocolError(fmt::format("empty message from {}", from));
  zmq::message_t head = frames.pop();
  if (head.size() != kHeaderSize)
    throw ProtocolError(fmt::format("message from {} has a {}-byte header, expected {}", from, head.size(), kHeaderSize));
  const auto* h = static_cast<const unsigned char*>(head.data());
  if (get<std::uint32_t>(h, 0) != kMagic)
    throw ProtocolError(fmt::format("message from {} is not a cosim message (bad magic)", from));
  const auto version = get<std::uint16_t>(h, 4);
  if (version != kVersion)
    throw ProtocolError(fmt::format("{} speaks protocol version {}, this coupler speaks version {}", from, version, kVersion));
  Message m;
  m.header.type = static_cast<Type>(get<std::uint16_t>(h, 6));
  m.header.window = get<std::uint64_t>(h, 8);
  m.header.iteration = get<std::uint32_t>(h, 16);
  m.header.flags = get<std::uint32_t>(h, 20);
  m.header.time = get<double>(h, 24);
  m.header.dt = get<double>(h, 32);
  m.header.value0 = get<double>(h, 40);
  m.header.value1 = get<double>(h, 48);
  m.header.fieldCount = get<std::uint32_t>(h, 56);
  m.header.features = get<std::uint32_t>(h, 60);
  if (m.header.type < Type::kHello || m.header.type > Type::kBye)
    throw ProtocolError(fmt::format("message from {} has unknown type {}", from, static_cast<int>(m.header.type)));
  if (m.header.type == Type::kError) {
    m.text = frames.empty() ? std::string("(no text)") : frames.popstr();
    return m;
  }
  if (frames.size() != 2 * static_cast<std::size_t>(m.header.fieldCount))
    throw ProtocolError(fmt::format("{} from {} declares {} fields but carries {} frames after the header",
                                    toString(m.header.type), from, m.header.fieldCount, frames.size()));
  m.fields.reserve(m.header.fieldCount);
  for (std::uint32_t i = 0; i < m.header.fieldCount; ++i) {
    Field f;
    f.name = frames.popstr();
    const zmq::message_t data = frames.pop();
    const auto* bytes = static_cast<const unsigned char*>(data.data());
    const bool sparse = f.name.rfind(kSparsePrefix, 0) == 0, update = f.name.rfind(kUpdatePrefix, 0) == 0;
    if (sparse) f.name.erase(0, std::strlen(kSparsePrefix));
    if (update) f.name.erase(0, std::strlen(kUpdatePrefix));
    const char* form = sparse ? "sparse " : update ? "update of " : "";
    if (data.size() % sizeof(double) != 0 || ((sparse || update) && data.size() % (2 * sizeof(double)) != sizeof(double)))
      throw ProtocolError(fmt::format("{}field \"{}\" from {} has {} bytes, {}", form, f.name, from, data.size(),
                                      sparse || update ? "not a length and (index, value) pairs"
                                                       : "not a whole number of float64"));
    const std::size_t count = data.size() / sizeof(double);
    auto nonFinite = [&](std::size_t index) {
      return ProtocolError(fmt::format("field \"{}\" from {} holds a non-finite value at index {}", f.name, from, index));
    };
    if (!sparse && !update) {
      f.data.resize(count);
      if (const std::size_t bad = copyFinite(bytes, count, f.data.data()); bad != count) throw nonFinite(bad);
    } else {
      const std::size_t entries = (count - 1) / 2;
      const auto n = get<std::uint64_t>(bytes, 0);
      // An update is applied to the recorded value in place (the record is what it is relative to),
      // then copied out once.
      std::vector<double>* target = &f.data;
      if (update) {
        const auto last = received ? received->find(f.name) : FieldMemory::iterator{};
        if (!received || last == received->end() || last->second.size() != n)
          throw ProtocolError(fmt::format("update of field \"{}\" from {} has no previous {} values to update", f.name,
                                          from, n));
        target = &last->second;
      } else {
        // A few bytes must not make the receiver allocate terabytes (found by fuzz_protocol): 2^27 values
        // (1 GB) is far beyond any interface field.
        if (n > kMaxFieldValues)
          throw ProtocolError(fmt::format("sparse field \"{}\" from {} declares {} values (at most {})", f.name, from, n,
                                          kMaxFieldValues));
        f.data.assign(n, 0.0);
      }
      std::vector<double> values(entries);
      const std::size_t bad = copyFinite(bytes + (1 + entries) * sizeof(double), entries, values.data());
      for (std::size_t k = 0; k < entries; ++k) {
        const auto index = get<std::uint64_t>(bytes, (1 + k) * sizeof(double));
        if (index >= n || (k > 0 && index <= get<std::uint64_t>(bytes, k * sizeof(double))))
          throw ProtocolError(fmt::format("{}field \"{}\" from {}: entry {} has index {} ({} values; indices must "
                                          "increase)",
                                          form, f.name, from, k, index, n));
        if (k == bad) throw nonFinite(index);
        (*target)[index] = values[k];
      }
      if (update) f.data = *target;
    }
    if (received && !update) (*received)[f.name] = f.data;
    m.fields.push_back(std::move(f));
  }
  return m;
}

std::uint16_t peekVersion(const zmq::multipart_t& frames) {
  if (frames.empty() || frames[0].size() != kHeaderSize) return 0;
  const auto* h = static_cast<const unsigned char*>(frames[0].data());
  return get<std::uint32_t>(h, 0) == kMagic ? get<std::uint16_t>(h, 4) : 0;
}

zmq::multipart_t encodeError(const std::string& text, std::uint16_t version) {
  Message m;
  m.header.type = Type::kError;
  m.text = text;
  zmq::multipart_t frames = encode(std::move(m));
  auto* h = static_cast<unsigned char*>(frames[0].data());
  put(h, 4, version);
  return frames;
}

std::optional<zmq::multipart_t> receive(zmq::socket_t& socket, std::chrono::milliseconds timeout) {
  zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
  try {
    if (zmq::poll(&item, 1, timeout) <= 0) return std::nullopt;
    zmq::multipart_t m;
    if (!m.recv(socket)) return std::nullopt;
    return m;
  } catch (const zmq::error_t& e) {
    // SIGTERM or Ctrl-C: the wait ends; the caller's signal flag says why.
    if (e.num() == EINTR) return std::nullopt;
    throw;
  }
}

}  // namespace cosim::protocol
