#include "element_registry.hpp"

#include "elements/membrane_tri3.hpp"
#include "elements/tet4.hpp"
#include "elements/truss.hpp"

namespace fem {

namespace {

using common::Interval;

const ElementType kTypes[] = {
    {"membrane_tri3", 2,
     [](const common::Config& e, const std::vector<std::uint32_t>& c, const std::vector<Vec3>& x,
        const ElementMaterial& m) -> std::unique_ptr<Element> {
       return std::make_unique<MembraneTri3>(
           c, x, MembraneTri3::Params{m.young, m.poisson, m.density, e.get("thickness", Interval::positive()),
                                      e.get("prestress", 0.0, Interval::nonNegative())});
     }},
    {"tet4", 3,
     [](const common::Config&, const std::vector<std::uint32_t>& c, const std::vector<Vec3>& x,
        const ElementMaterial& m) -> std::unique_ptr<Element> {
       return std::make_unique<Tet4>(c, x, Tet4::Params{m.young, m.poisson, m.density});
     }},
    {"truss", 1,
     [](const common::Config& e, const std::vector<std::uint32_t>& c, const std::vector<Vec3>& x,
        const ElementMaterial& m) -> std::unique_ptr<Element> {
       return std::make_unique<Truss>(c, x,
                                      Truss::Params{m.young, m.density, e.get("area", Interval::positive()),
                                                    e.get("prestress", 0.0, Interval::nonNegative()),
                                                    e.get<bool>("tension_only", false)});
     }},
};

}  // namespace

const common::Registry<ElementType>& elementTypes() {
  static constexpr common::Registry<ElementType> kRegistry{kTypes, "element type"};
  return kRegistry;
}

}  // namespace fem
