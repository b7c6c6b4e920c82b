#pragma once
// The wire format of the coupling protocol (docs/protocol.md is the normative text). ZeroMQ multipart
// messages: frame 0 a 64-byte little-endian header, then per field a name frame ("mesh/field", UTF-8)
// and a data frame (raw float64, little-endian; or, named "sparse:mesh/field", its nonzero entries).
// ERROR messages carry one text frame instead.

#include <bit>
#include <chrono>
#include <map>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <zmq.hpp>
#include <zmq_addon.hpp>

namespace cosim::protocol {

static_assert(std::endian::native == std::endian::little, "the protocol is little-endian; add byte swapping");

inline constexpr std::uint32_t kMagic = 0x4D534F43;  // "COSM"
// Version 2: participants identify themselves in HELLO (name and the run's token), not by their
// connection's routing identity; heartbeats travel on the participant's own connection, both ways.
inline constexpr std::uint16_t kVersion = 2;
inline constexpr std::size_t kHeaderSize = 64;
/// The most values a field may have (a sparse field declares its length: this bounds what a message of
/// a few bytes can make the receiver allocate).
inline constexpr std::uint64_t kMaxFieldValues = std::uint64_t{1} << 27;

enum class Type : std::uint16_t {
  kHello = 1,      ///< participant → coupler: meshes, reads and writes
  kWelcome = 2,    ///< coupler → participant: accepted; time window and end time
  kAdvance = 3,    ///< coupler → participant: inputs of one window iteration, flags
  kResult = 4,     ///< participant → coupler: outputs, solver wall time, stable dt
  kFinalize = 5,   ///< coupler → participant: stop
  kError = 6,      ///< either way: a text frame; the run stops
  kHeartbeat = 7,  ///< participant → coupler while it computes; coupler → participant while it waits
  kBye = 8,        ///< participant → coupler: acknowledged FINALIZE, exiting
};

enum Flag : std::uint32_t {
  kSaveCheckpoint = 1u << 0,     ///< first iteration of a window: save state before advancing
  kRestoreCheckpoint = 1u << 1,  ///< repeat the window: restore the saved state first
  kLastIteration = 1u << 2,      ///< the previous iteration converged (informational)
  kWriteOutput = 1u << 3,        ///< the window that ends now is final: write output
  /// ERROR only: the participant's solver diverged (a numerical instability, its exit code 3), as
  /// opposed to a failure of input, I/O or the protocol. The coupler then ends with exit 3 too.
  kErrorInstability = 1u << 4,
  /// ADVANCE (first iteration of a window): before advancing, write the state at the window start to
  /// the path in the field "checkpoint:PATH" (no data), atomically; RESULT then means it is on disk.
  kWriteCheckpoint = 1u << 5,
  /// RESULT only (feature kRetries): the solver diverged in this iteration. No outputs; one field
  /// "diverged:TEXT" (no data) says why. The participant waits for the next ADVANCE, which restores.
  kDiverged = 1u << 6,
};

/// Optional features, negotiated in the header's `features` word: HELLO lists what a participant
/// understands, WELCOME what the coupler will use with it.
enum Feature : std::uint32_t {
  kSparseFields = 1u << 0,  ///< a field that is mostly +0.0 may travel as its other entries ("sparse:")
  kFieldUpdates = 1u << 1,  ///< a field may travel as the entries that changed since its previous
                            ///< message on the same connection and direction ("update:")
  kCheckpoints = 1u << 2,   ///< HELLO: the participant writes on-disk checkpoints (kWriteCheckpoint)
  kRetries = 1u << 3,       ///< HELLO: a divergence of its solver is a RESULT with kDiverged, not an ERROR:
                            ///< the coupler may repeat the window shorter (adaptive windows)
};
inline constexpr std::uint32_t kAllFeatures = kSparseFields | kFieldUpdates | kCheckpoints | kRetries;

struct Header {
  Type type = Type::kHello;
  std::uint64_t window = 0;
  std::uint32_t iteration = 0;
  std::uint32_t flags = 0;
  double time = 0.0;    ///< window start time [s]
  double dt = 0.0;      ///< window length [s]
  double value0 = 0.0;  ///< RESULT: solver wall time of this window [s]; WELCOME: end time [s]
  double value1 = 0.0;  ///< RESULT: the participant's stable time step [s] (0: none)
  std::uint32_t fieldCount = 0;
  std::uint32_t features = 0;  ///< HELLO, WELCOME: Feature bits
};

struct Field {
  std::string name;  ///< "mesh/field"
  std::vector<double> data;
};

struct Message {
  Header header;
  std::vector<Field> fields;
  std::string text;  ///< ERROR only
  const Field* field(const std::string& name) const;
};

/// A malformed or unexpected message; the text names the sender and what was wrong.
class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

const char* toString(Type t);

/// The last values of each field one side sent on a connection, or received from it: what "update:"
/// fields are relative to.
using FieldMemory = std::map<std::string, std::vector<double>>;

/// The message's frames; dense field data move into them without a copy. A field of which fewer than
/// a quarter of the values are not +0.0 (kSparseFields), or differ from its previous message recorded
/// in `sent` (kFieldUpdates), travels as those entries, whichever is fewer. With kFieldUpdates, `sent`
/// (required then) records every field sent.
zmq::multipart_t encode(Message m, std::uint32_t features = 0, FieldMemory* sent = nullptr);
/// Decodes frames (without any routing identity); sparse and update fields come out dense. With
/// `received`, every field is recorded there (and update fields are applied to it). `from` names the
/// sender in error messages.
Message decode(zmq::multipart_t& frames, const std::string& from, FieldMemory* received = nullptr);

/// The protocol version a message's header states (0: not a cosim header), read before decode() so a
/// peer of another version can be answered in words it understands.
std::uint16_t peekVersion(const zmq::multipart_t& frames);
/// An ERROR message in protocol `version`'s header layout (the magic, version and type words are the
/// same in every version): a refusal a participant of that version can print.
zmq::multipart_t encodeError(const std::string& text, std::uint16_t version = kVersion);

/// Receives one multipart message within `timeout`; std::nullopt on timeout or when a signal
/// interrupted the wait (the caller checks its own signal flag).
std::optional<zmq::multipart_t> receive(zmq::socket_t& socket, std::chrono::milliseconds timeout);

}  // namespace cosim::protocol
