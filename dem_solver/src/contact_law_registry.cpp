// The contact laws (common/registry.hpp: one entry each, reading its own keys).
#include <fmt/format.h>

#include "common/config.hpp"
#include "common/registry.hpp"
#include "contact/cohesive_frictional.hpp"
#include "contact/hertz_mindlin.hpp"
#include "contact/linear_spring_dashpot.hpp"
#include "dem/contact_law.hpp"

namespace dem {

namespace {

using Factory = std::unique_ptr<ContactLaw> (*)(const common::Config&, const Material&, const Material&,
                                                const InteractionParams&, const LawOverride&);

struct Entry {
  const char* name;
  Factory make;
};

// Every deformable side needs a modulus, and two rigid sides have no stiffness.
void requireModuli(const char* law, const Material& a, const Material& b) {
  for (const Material* m : {&a, &b})
    if (!m->rigid && !(m->youngModulus > 0))
      throw common::ConfigError(fmt::format(
          "{} needs young_modulus > 0 for material \"{}\" (found {}), or rigid: true for a wall.", law, m->name,
          m->youngModulus));
  if (a.rigid && b.rigid)
    throw common::ConfigError(fmt::format(
        "{} between two rigid materials (\"{}\", \"{}\") has no stiffness; one side needs young_modulus.", law,
        a.name, b.name));
}

const Entry kLaws[] = {
    {"cohesive_frictional",
     [](const common::Config& c, const Material& a, const Material& b, const InteractionParams& p,
        const LawOverride& change) -> std::unique_ptr<ContactLaw> {
       // Its own modulus where the materials' serve another law (a block whose surface meets a soft net).
       const double modulus = c.get("young_modulus", 0.0, common::Interval::nonNegative());
       Material ma = a, mb = b;
       for (Material* m : {&ma, &mb})
         if (modulus > 0.0 && !m->rigid) m->youngModulus = modulus;
       requireModuli("cohesive_frictional", ma, mb);
       CohesiveFrictional::Strength s;
       s.tensile = c.get("tensile_strength", 0.0, common::Interval::nonNegative());
       s.cohesion = c.get("cohesion", 0.0, common::Interval::nonNegative());
       s.interactionRadius = c.get("interaction_radius", 1.0, common::Interval::closed(1.0, 10.0));
       const double ratio = c.get("shear_stiffness_ratio", 0.25, common::Interval::positive());
       if (!change.bonds) s.tensile = s.cohesion = 0.0;
       return std::make_unique<CohesiveFrictional>(ma, mb, ratio, s, p);
     }},
    {"hertz_mindlin",
     [](const common::Config&, const Material& a, const Material& b, const InteractionParams& p,
        const LawOverride&) -> std::unique_ptr<ContactLaw> {
       requireModuli("hertz_mindlin", a, b);
       return std::make_unique<HertzMindlin>(a, b, p);
     }},
    {"linear_spring_dashpot",
     [](const common::Config& c, const Material&, const Material&, const InteractionParams& p,
        const LawOverride&) -> std::unique_ptr<ContactLaw> {
       const double kn = c.get("stiffness_normal", common::Interval::positive());
       const double kt = c.get("stiffness_tangential", 2.0 / 7.0 * kn, common::Interval::positive());
       return std::make_unique<LinearSpringDashpot>(kn, kt, p);
     }},
};

constexpr common::Registry<Entry> kRegistry{kLaws, "contact law"};

}  // namespace

std::vector<std::string> contactLawNames() { return kRegistry.names(); }

std::unique_ptr<ContactLaw> makeContactLaw(const std::string& type, const common::Config& params, const Material& a,
                                           const Material& b, const LawOverride& change) {
  InteractionParams p;
  p.restitution = params.get("restitution", 1.0, common::Interval{0.0, 1.0, true, false});
  p.friction = params.get("friction", 0.0, common::Interval::nonNegative());
  p.rollingFriction = params.get("rolling_friction", 0.0, common::Interval::nonNegative());
  if (change.friction) p.friction = *change.friction;
  const Entry* e = kRegistry.find(type);
  if (!e) params.failAt("law", fmt::format("unknown contact law \"{}\".", type));
  try {
    return e->make(params, a, b, p, change);
  } catch (const std::invalid_argument& err) {
    params.failAt("restitution", err.what());
  }
}

}  // namespace dem
