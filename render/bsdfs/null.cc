// `null` (Mitsuba 3): no surface for light; every ray passes straight through (the null lobe:
// wi = -wo, weight 1) and shadow rays are not blocked. For shapes that only emit, or that only
// bound a volume.
#include "render/bsdfs/registry.h"

namespace irfarm {
namespace {

class NullBsdf final : public Bsdf {
 public:
  uint32_t Flags() const override { return kNullTransmission | kTwoSidedFlag; }
  Vec3 Eval(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override {
    return Vec3();
  }
  float Pdf(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override { return 0; }
  BsdfSample Sample(const BsdfContext&, const Vec3& wo, float, float, float,
                    uint32_t lobes) const override {
    BsdfSample s;
    if (!(lobes & kNullTransmission)) return s;
    s.wi = -wo;
    s.weight = Vec3(1.0f);
    s.lobe = kNullTransmission;
    return s;
  }
  float PassThrough(const BsdfContext&, float, bool, bool) const override { return 1; }
};

absl::Status Parse(BsdfParams&) { return absl::OkStatus(); }

std::unique_ptr<Bsdf> Build(const BsdfDesc&, const BsdfBuildContext&) {
  return std::make_unique<NullBsdf>();
}

}  // namespace

extern const BsdfPlugin kNullBsdf = {"null", Parse, Build};

}  // namespace irfarm
