#include "data_path.hpp"

#include <algorithm>
#include <chrono>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/errors.hpp"
#include "common/log.hpp"
#include "common/state_archive.hpp"

namespace cosim {

namespace pr = protocol;
using Clock = std::chrono::steady_clock;

namespace {
double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// A map of interface fields in a checkpoint: the names, then the values by position (names hold '/').
void archiveFields(common::StateArchive& a, const std::string& name, Fields& fields) {
  auto scope = a.scope(name);
  std::vector<std::string> names;
  for (const auto& [key, values] : fields) names.push_back(key);
  a.io("names", names);
  for (std::size_t i = 0; i < names.size(); ++i) a.io(std::to_string(i), fields[names[i]]);
}

std::string describeSizes(const std::map<std::string, std::size_t>& sizes) {
  std::string text;
  for (const auto& [name, n] : sizes) text += fmt::format("{}{} ({} values)", text.empty() ? "" : ", ", name, n);
  return text;
}
}  // namespace

DataPath::DataPath(const CoupledScene& scene, Connections& peers, const Position& at)
    : scene_(scene), peers_(peers), at_(at) {}

void DataPath::build(const std::vector<std::string>& schemeMeshes) {
  auto meshOf = [](const std::string& field) { return field.substr(0, field.find('/')); };
  auto schemes = [&](const std::string& field) {
    return std::find(schemeMeshes.begin(), schemeMeshes.end(), meshOf(field)) != schemeMeshes.end();
  };
  const auto t0 = Clock::now();
  auto index = [&](const std::string& n) {
    const auto& all = peers_.all();
    return static_cast<std::size_t>(
        std::find_if(all.begin(), all.end(), [&](const Participant& l) { return l.spec.name == n; }) - all.begin());
  };
  for (const auto& x : scene_.exchanges) {
    Route r{&x, index(x.from), index(x.to), nullptr, 0, x.fromMesh + "/" + x.field, x.toMesh + "/" + x.field};
    Participant &from = peers_[r.from], &to = peers_[r.to];
    if (!from.writes.count(r.write)) {
      std::vector<std::string> writes;
      for (const auto& [k, c] : from.writes) writes.push_back(k);
      peers_.fail(fmt::format("exchange {} → {}: participant \"{}\" does not write {} (it writes: {})", x.from, x.to,
                              x.from, r.write, fmt::join(writes, ", ")));
    }
    if (!to.reads.count(r.read))
      peers_.fail(fmt::format("exchange {} → {}: participant \"{}\" does not read {}", x.from, x.to, x.to, r.read));
    r.components = from.writes[r.write];
    if (to.reads[r.read] != r.components)
      peers_.fail(fmt::format("exchange {}: {} writes {} components, {} reads {}", x.field, x.from, r.components, x.to,
                              to.reads[r.read]));
    if (!from.meshes.count(x.fromMesh) || !to.meshes.count(x.toMesh))
      peers_.fail(fmt::format("exchange {}: mesh {} of {} or {} of {} was not declared", x.field, x.fromMesh, x.from,
                              x.toMesh, x.to));
    try {
      // Consistent: from → to. Conservative: the transpose of the consistent map to → from.
      r.map = x.conservative ? makeMapping(x.mapping, to.meshes[x.toMesh], from.meshes[x.fromMesh])
                             : makeMapping(x.mapping, from.meshes[x.fromMesh], to.meshes[x.toMesh]);
    } catch (const std::exception& e) {
      peers_.fail(fmt::format("exchange {} ({} → {}): {}", x.field, x.from, x.to, e.what()));
    }
    if (r.map->copies() && x.mapping != "identity")
      common::logger("cosim")->info("exchange {} ({} → {}): every node of one mesh is a node of the other: {} copies "
                                    "values",
                                    x.field, x.from, x.to, x.mapping);
    to.inputs[r.read].assign(to.meshes[x.toMesh].nodes.size() * static_cast<std::size_t>(r.components), 0.0);
    routes_.push_back(std::move(r));
  }
  for (auto& p : peers_.all())
    for (const auto& [name, comps] : p.reads)
      if (const auto mesh = p.meshes.find(meshOf(name)); schemes(name) && mesh != p.meshes.end())
        p.inputs[name].assign(mesh->second.nodes.size() * static_cast<std::size_t>(comps), 0.0);
  for (std::size_t p = 0; p < peers_.size(); ++p)
    for (const auto& [name, comps] : peers_[p].writes)
      if (!schemes(name) && std::none_of(routes_.begin(), routes_.end(), [&](const Route& r) { return r.from == p && r.write == name; }))
        peers_[p].unused.insert(name);
  for (auto& p : peers_.all())
    for (const auto& [name, comps] : p.reads)
      if (!p.inputs.count(name))
        peers_.fail(fmt::format("participant \"{}\" reads {} but no exchange provides it", p.spec.name, name));
  mappingSeconds_ += seconds(Clock::now() - t0);
}

std::vector<std::string> DataPath::readFields(std::size_t p) const {
  std::vector<std::string> fields;
  for (const auto& [name, comps] : peers_[p].writes)
    if (std::any_of(routes_.begin(), routes_.end(), [&](const Route& r) { return r.from == p && r.write == name; }))
      fields.push_back(name);
  return fields;
}

void DataPath::advance(std::size_t index, std::uint32_t flags, double dt, const std::filesystem::path& checkpoint) {
  Participant& p = peers_[index];
  pr::Message m;
  m.header.type = pr::Type::kAdvance;
  m.header.window = at_.window;
  m.header.iteration = at_.iteration;
  m.header.flags = flags;
  m.header.time = at_.time;
  m.header.dt = dt;
  for (const auto& [name, values] : p.inputs) m.fields.push_back({name, values});
  if (!checkpoint.empty()) m.fields.push_back({"checkpoint:" + checkpoint.string(), {}});
  for (const auto& name : p.keepAdvanced) p.advanced[name] = p.inputs[name];
  p.sentAt = Clock::now();
  peers_.send(p, std::move(m));
}

void DataPath::collect(std::span<const std::size_t> ps) {
  double slowest = 0.0;
  peers_.collect(ps, [&](Participant& p, pr::Message r) {
    slowest = std::max(slowest, r.header.value0);
    take(p, std::move(r));
  });
  criticalSolverSeconds_ += slowest;
  // Every answer is in before the window is repeated: none may arrive late into the repeat.
  for (std::size_t p : ps)
    if (!peers_[p].diverged.empty()) throw ParticipantDiverged{peers_[p].spec.name, peers_[p].diverged};
}

std::size_t DataPath::largestAdvance() const {
  std::size_t largest = 0;
  for (const auto& p : peers_.all()) {
    std::size_t bytes = 0;
    for (const auto& [name, values] : p.inputs) bytes += values.size() * sizeof(double);
    largest = std::max(largest, bytes);
  }
  return largest;
}

void DataPath::take(Participant& p, pr::Message r) {
  p.waitSeconds += seconds(Clock::now() - p.sentAt);
  p.diverged.clear();
  if (r.header.flags & pr::kDiverged) {
    const auto why = std::find_if(r.fields.begin(), r.fields.end(),
                                  [](const pr::Field& f) { return f.name.rfind("diverged:", 0) == 0; });
    if (!(peers_.router().features(peers_.indexOf(p)) & pr::kRetries) || why == r.fields.end() || r.fields.size() != 1)
      peers_.fail(fmt::format("participant \"{}\" sent a RESULT flagged diverged {} (window {}, iteration {})",
                              p.spec.name,
                              why == r.fields.end() ? "without its diverged:REASON field"
                                                    : "with outputs, or without having offered retries in HELLO",
                              at_.window, at_.iteration));
    p.diverged = why->name.substr(9);
    if (p.diverged.empty()) p.diverged = "(no reason given)";
    return;
  }
  p.solverSeconds += r.header.value0;
  p.stableDt = r.header.value1;
  p.outputs.clear();
  for (auto& f : r.fields) {
    const auto w = p.writes.find(f.name);
    if (w == p.writes.end())
      peers_.fail(fmt::format("participant \"{}\" sent the field {} in RESULT, which it did not declare as a write "
                              "(window {}, iteration {})",
                              p.spec.name, f.name, at_.window, at_.iteration));
    const auto mesh = p.meshes.find(f.name.substr(0, f.name.rfind('/')));
    const std::size_t expected =
        (mesh == p.meshes.end() ? 0 : mesh->second.nodes.size()) * static_cast<std::size_t>(w->second);
    if (f.data.size() != expected)
      peers_.fail(fmt::format("participant \"{}\" sent {} values of {} in RESULT; its mesh has {} nodes × {} components "
                              "= {} (window {}, iteration {})",
                              p.spec.name, f.data.size(), f.name, expected / static_cast<std::size_t>(w->second),
                              w->second, expected, at_.window, at_.iteration));
    p.outputs[f.name] = std::move(f.data);
  }
  for (const auto& [name, comps] : p.writes)
    if (!p.outputs.count(name) && !p.unused.count(name))
      peers_.fail(fmt::format("participant \"{}\" sent RESULT without its write {}", p.spec.name, name));
}

void DataPath::deliver(std::size_t p) {
  const auto t0 = Clock::now();
  for (auto& r : routes_) {
    if (r.from != p) continue;
    const auto& data = peers_[p].outputs.at(r.write);
    auto& target = peers_[r.to].inputs[r.read];
    try {
      if (r.spec->conservative) r.map->conservative(data, target, r.components);
      else r.map->consistent(data, target, r.components);
    } catch (const std::exception& e) {
      peers_.fail(fmt::format("exchange {} ({} → {}): {}", r.spec->field, r.spec->from, r.spec->to, e.what()));
    }
  }
  mappingSeconds_ += seconds(Clock::now() - t0);
}

void DataPath::archive(common::StateArchive& a) {
  // What this scene's participants exchange: a checkpoint's interface data must have the same fields and
  // sizes (a changed mesh or exchange is another run).
  auto sizes = [&] {
    std::map<std::string, std::size_t> s;
    for (const auto& p : peers_.all())
      for (const auto& [name, values] : p.inputs) s[p.spec.name + " reads " + name] = values.size();
    return s;
  };
  const auto expected = sizes();
  a.io("mapping_s", mappingSeconds_);
  for (auto& p : peers_.all()) {
    auto own = a.scope("participants/" + p.spec.name);
    archiveFields(a, "inputs", p.inputs);
    archiveFields(a, "outputs", p.outputs);
    a.io("solver_s", p.solverSeconds), a.io("wait_s", p.waitSeconds);
  }
  if (!a.reading()) return;
  if (const auto found = sizes(); found != expected)
    throw common::ConfigError(fmt::format("{}: a checkpoint of another coupled scene: its interface data are {}; this "
                                          "scene's are {}",
                                          a.path().string(), describeSizes(found), describeSizes(expected)));
  for (const auto& p : peers_.all())
    for (const auto& [name, values] : p.outputs) {
      const auto mesh = p.meshes.find(name.substr(0, name.rfind('/')));
      const auto w = p.writes.find(name);
      if (w == p.writes.end() || mesh == p.meshes.end() ||
          values.size() != mesh->second.nodes.size() * static_cast<std::size_t>(w->second))
        throw common::ConfigError(fmt::format("{}: a checkpoint of another coupled scene: participant \"{}\"'s {} holds "
                                              "{} values",
                                              a.path().string(), p.spec.name, name, values.size()));
    }
}

}  // namespace cosim
