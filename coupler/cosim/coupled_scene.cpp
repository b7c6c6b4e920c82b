// Reading a coupled scene (coupler/README.md, "Scene keys") and the participant overrides of the
// command line; every error a common::ConfigError with its location.
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <fstream>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <zmq.h>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "coupler.hpp"
#include "cosim/mapping.hpp"
#include "schemes/scheme.hpp"

namespace cosim {

namespace fs = std::filesystem;
using common::Config;
using common::Interval;

namespace {

// `coupling.curve`: the coupler's secret key and the external participants' public keys.
void readCurve(const Config& c, CoupledScene& s) {
  if (Config curve = c.child("curve")) {
    const fs::path file = curve.filePath("secret_key_file");
    struct stat st {};
    if (::stat(file.c_str(), &st) == 0 && (st.st_mode & 077))
      curve.failAt("secret_key_file", fmt::format("{} can be read by other users (mode {:o}): chmod 600 it.", file.string(),
                                                  st.st_mode & 0777));
    std::ifstream in(file);
    std::getline(in, s.coupling.curveSecretKey);
    char pub[41] = {};
    if (s.coupling.curveSecretKey.size() != 40 || zmq_curve_public(pub, s.coupling.curveSecretKey.c_str()) != 0)
      curve.failAt("secret_key_file", fmt::format("{} does not hold a CURVE secret key (40 Z85 characters on its first "
                                                  "line; `cosim keys PREFIX` makes one).",
                                                  file.string()));
    s.coupling.curveAllowedKeys = curve.get<std::vector<std::string>>("allowed_keys", {});
    for (std::size_t i = 0; i < s.coupling.curveAllowedKeys.size(); ++i) {
      std::uint8_t raw[32];
      if (s.coupling.curveAllowedKeys[i].size() != 40 || !zmq_z85_decode(raw, s.coupling.curveAllowedKeys[i].c_str()))
        curve.at("allowed_keys").elements()[i].fail("is not a CURVE public key (40 Z85 characters, a PREFIX.public of `cosim keys`).");
    }
  }
}

// `coupling:`; returns the per-field tolerances, which the exchanges check.
std::vector<std::pair<std::string, Config>> readCoupling(const Config& cfg, CoupledScene& s) {
  const Config c = cfg.at("coupling");
  s.coupling.scheme = c.choice("scheme", schemeNames(), "implicit");
  s.coupling.window = c.get("time_window", Interval::positive());
  s.coupling.endTime = c.get("end_time", Interval::positive());
  // The windows end at end_time exactly: a remainder was rounded away (end_time 0.02 s with 1 s windows ran
  // no window at all and ended "ok").
  common::requireWholeSteps(c, "end_time", s.coupling.endTime, s.coupling.window,
                            {"time_window", "window", "coupling windows", 1e9});
  // The iteration's keys (max_iterations, tolerance, acceleration, …) are the scheme's own: an explicit
  // scheme, which does not iterate, refuses them (schemes.cpp).
  std::vector<std::pair<std::string, Config>> fieldTolerances = readSchemeKeys(c, s.coupling);
  s.coupling.energyTolerance = c.get("energy_tolerance", 0.05, Interval{0.0, 1e3, true, true});
  s.coupling.timeoutSeconds = c.get("timeout", 60.0, Interval::positive());
  s.coupling.firstAnswerTimeoutSeconds =
      c.get("first_answer_timeout", std::max(600.0, s.coupling.timeoutSeconds), Interval::positive());
  s.coupling.endpoint = c.get<std::string>("endpoint", "");
  // ipc://PATH (a file with permissions) or tcp:// only: an abstract ipc://@NAME has no permissions at all,
  // and inproc:// cannot reach another process.
  if (const std::string& ep = s.coupling.endpoint; !ep.empty()) {
    if (ep.rfind("ipc://@", 0) == 0)
      c.failAt("endpoint", "is an abstract socket, which any local user can reach (it has no file permissions): use "
                           "ipc://PATH, or leave coupling.endpoint out (a private socket in a 0700 folder).");
    if (ep.rfind("ipc://", 0) != 0 && ep.rfind("tcp://", 0) != 0)
      c.failAt("endpoint", "must be ipc://PATH or tcp://HOST:PORT (participants are other processes), or left out "
                           "(a private ipc socket).");
  }
  s.coupling.checkpointInterval = c.get<int>("checkpoint_interval", 0);
  if (s.coupling.checkpointInterval < 0) c.failAt("checkpoint_interval", "must be 0 (no checkpoints) or a number of windows.");
  readCurve(c, s);
  // Opt-in: `poll` changes a machine-wide setting for as long as the run lasts (issue 30).
  s.coupling.pollingIdle = c.choice("idle_cpus", {"poll", "sleep"}, "sleep") == "poll";
  return fieldTolerances;
}

// `participants.NAME`: a command to launch, or an external participant; its credential.
ParticipantSpec readParticipant(const std::string& name, const Config& p, const fs::path& sceneDir) {
  ParticipantSpec spec;
  spec.name = name;
  spec.external = p.get<bool>("external", false);
  if (!spec.external) {
    spec.command = p.get<std::vector<std::string>>("command");
    if (spec.command.empty()) p.failAt("command", "give the program and its arguments, e.g. [fem_solver, bar.yaml].");
    const fs::path written = p.at("command").location().file;
    spec.workDir = fs::is_regular_file(written) ? fs::absolute(written).parent_path() : sceneDir;
    spec.threads = p.get<int>("threads", 0);
    if (spec.threads < 0) p.failAt("threads", "must be ≥ 1 (or 0: the participant's default).");
  }
  // The participant's credential (Router): given, read from a file only its owner can read, or made
  // fresh for this run.
  if (auto t = p.find<std::string>("token")) {
    if (t->size() < 16) p.failAt("token", "is too short to be a secret: give at least 16 characters.");
    spec.token = *t;
  } else if (auto f = p.find<std::string>("token_file")) {
    const fs::path written = p.at("token_file").location().file;
    const fs::path path = (fs::is_regular_file(written) ? fs::absolute(written).parent_path() : sceneDir) / *f;
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) p.failAt("token_file", fmt::format("{} cannot be read: {}", path.string(), std::strerror(errno)));
    if (st.st_mode & 077)
      p.failAt("token_file", fmt::format("{} can be read by other users (mode {:o}): chmod 600 it.", path.string(),
                                         st.st_mode & 0777));
    std::ifstream in(path);
    std::getline(in, spec.token);
    if (spec.token.size() < 16) p.failAt("token_file", fmt::format("{} holds no token of at least 16 characters.", path.string()));
  }
  return spec;
}

// `exchanges:`, between the participants `order` lists.
void readExchanges(const Config& cfg, const std::vector<std::string>& order, CoupledScene& s) {
  // A scheme that moves its own data (the bridging domain's overlap) may have no exchange.
  const bool ownData = !schemeMeshes(s.coupling).empty();
  for (const auto& e : ownData && !cfg.has("exchanges") ? std::vector<Config>{} : cfg.at("exchanges").elements()) {
    ExchangeSpec x;
    x.from = e.choice("from", order);
    x.to = e.choice("to", order);
    if (x.from == x.to)
      e.failAt("to", fmt::format("\"{}\" exchanges with itself; an exchange goes from one participant to another.", x.to));
    x.field = e.get<std::string>("field");
    x.fromMesh = e.get<std::string>("from_mesh", "interface");
    x.toMesh = e.get<std::string>("to_mesh", "interface");
    x.mapping = e.choice("mapping", mappingNames(), "nearest_projection");
    x.conservative = e.get<bool>("conservative", false);
    s.exchanges.push_back(x);
  }
  if (s.exchanges.empty() && !ownData) cfg.failAt("exchanges", "list at least one exchange.");
}

// `order:`, the participants' order (every one, once).
void applyOrder(const Config& cfg, CoupledScene& s) {
  if (auto o = cfg.find<std::vector<std::string>>("order")) {
    std::vector<ParticipantSpec> sorted;
    for (const auto& n : *o) {
      auto it = std::find_if(s.participants.begin(), s.participants.end(), [&](const auto& p) { return p.name == n; });
      if (it == s.participants.end()) cfg.failAt("order", fmt::format("\"{}\" is not a participant.", n));
      // [right, right] started right twice and left never.
      if (std::any_of(sorted.begin(), sorted.end(), [&](const auto& p) { return p.name == n; }))
        cfg.failAt("order", fmt::format("lists \"{}\" twice; list every participant once.", n));
      sorted.push_back(*it);
    }
    if (sorted.size() != s.participants.size()) cfg.failAt("order", "must list every participant once.");
    s.participants = sorted;
  }
}

}  // namespace

CoupledScene loadCoupledScene(const Config& cfg) {
  CoupledScene s;
  s.sceneDir = fs::absolute(cfg.sceneFile()).parent_path();
  const std::vector<std::pair<std::string, Config>> fieldTolerances = readCoupling(cfg, s);
  std::vector<std::string> order;
  for (const auto& [name, p] : cfg.at("participants").entries()) {
    s.participants.push_back(readParticipant(name, p, s.sceneDir));
    order.push_back(name);
  }
  if (s.participants.size() < 2) cfg.failAt("participants", "a coupled scene needs at least two participants.");
  // A CURVE coupler admits in the handshake only the keys it knows: the launched participants' (made for
  // the run) and these.
  if (!s.coupling.curveSecretKey.empty() && s.coupling.curveAllowedKeys.empty())
    for (const auto& p : s.participants)
      if (p.external)
        cfg.at("coupling").at("curve").failAt(
            "allowed_keys", fmt::format("list the public key of external participant \"{}\" (the PREFIX.public of its "
                                        "`cosim keys PREFIX`): a CURVE coupler admits only the keys it knows.",
                                        p.name));
  applyOrder(cfg, s);
  readExchanges(cfg, order, s);
  for (const auto& [name, f] : fieldTolerances) {
    std::vector<std::string> fields;
    for (const auto& x : s.exchanges) fields.push_back(x.field);
    if (std::find(fields.begin(), fields.end(), name) == fields.end()) {
      const auto hint = common::suggest(name, fields);
      f.fail(fmt::format("\"{}\" is not a field of any exchange (they exchange: {}).{}", name, fmt::join(fields, ", "),
                         hint ? fmt::format(" Did you mean \"{}\"?", *hint) : std::string()));
    }
  }
  return s;
}

std::map<std::string, std::vector<std::string>> takeParticipantOverrides(std::vector<std::string>& overrides) {
  std::map<std::string, std::vector<std::string>> byName;
  std::vector<std::string> own;
  for (const auto& o : overrides) {
    const auto colon = o.find(':'), eq = o.find('=');
    if (colon != std::string::npos && (eq == std::string::npos || colon < eq))
      byName[o.substr(0, colon)].push_back(o.substr(colon + 1));
    else
      own.push_back(o);
  }
  overrides = own;
  return byName;
}

void applyParticipantOverrides(CoupledScene& scene, const std::map<std::string, std::vector<std::string>>& byName) {
  for (const auto& [name, sets] : byName) {
    auto it = std::find_if(scene.participants.begin(), scene.participants.end(),
                           [&](const ParticipantSpec& p) { return p.name == name; });
    std::vector<std::string> names;
    for (const auto& p : scene.participants) names.push_back(p.name);
    if (it == scene.participants.end()) {
      std::string hint;
      if (auto s = common::suggest(name, names)) hint = fmt::format(" Did you mean \"{}\"?", *s);
      throw common::ConfigError(fmt::format("--set {}:{}: the scene has no participant \"{}\" (it has: {}).{}", name,
                                    sets.front(), name, fmt::join(names, ", "), hint));
    }
    if (it->external)
      throw common::ConfigError(fmt::format("--set {}:{}: participant \"{}\" is external (started by hand): give it the "
                                    "override on its own command line.",
                                    name, sets.front(), name));
    for (const auto& s : sets) it->command.insert(it->command.end(), {"--set", s});
  }
}

}  // namespace cosim
