// The table of effects (effect_table.hpp) against methods.md section 7: the kinds, the names of
// the parameters, the ambiguous pairs and the one Stribeck start grid.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "friction/effect_table.hpp"
#include "friction/extensions.hpp"

namespace test_effect_table {
namespace {

using friction::Effect;
using friction::effect_info;
using friction::EffectKind;
using friction::kAllEffects;

TEST(EffectTable, KindsAreThoseOfMethodsSection7) {
  // "Effects that change the friction level (stribeck, asymmetry, position-dependence, drift,
  // normal-load) act on the elements' slip forces ... viscous, offset and inertia are added terms."
  const std::set<Effect> level{Effect::stribeck, Effect::asymmetry, Effect::position_dependence,
                               Effect::drift, Effect::normal_load};
  const std::set<Effect> added{Effect::viscous, Effect::offset, Effect::inertia};
  for (Effect e : kAllEffects) {
    EXPECT_EQ(friction::is_level_effect(e), level.count(e) == 1) << effect_info(e).name;
    EXPECT_EQ(effect_info(e).kind == EffectKind::added, added.count(e) == 1) << effect_info(e).name;
  }
}

TEST(EffectTable, MainParameterIsOneOfTheParametersAndBoxesAreOrdered) {
  const friction::RecordScales scales{2.0, 10.0, 1e-3};
  for (Effect e : kAllEffects) {
    const auto& info = effect_info(e);
    ASSERT_NE(friction::find_parameter(e, info.main_parameter), nullptr) << info.name;
    for (const auto& p : info.parameters) {
      EXPECT_LT(p.lower(scales), p.upper(scales)) << info.name << "." << p.name;
      EXPECT_EQ(friction::parameter_unit(p.name), p.unit) << p.name;
    }
  }
  // The boxes the fits used before the table, at these scales (F0 = 2 N, T = 10 s, vmax = 1 mm/s).
  const auto box = [&](Effect e, const char* name) {
    const auto* p = friction::find_parameter(e, name);
    return std::pair{p->lower(scales), p->upper(scales)};
  };
  EXPECT_EQ(box(Effect::stribeck, "static"), std::pair(0.05 * 2.0, 20.0 * 2.0));
  EXPECT_EQ(box(Effect::stribeck, "stribeck_velocity"), std::pair(1e-6 * 1e-3, 10.0 * 1e-3));
  EXPECT_EQ(box(Effect::frictional_lag, "lag_time"), std::pair(0.0, 10.0 / 4));
  EXPECT_EQ(box(Effect::drift, "relative_rate"), std::pair(-0.9 / 10.0, 5.0 / 10.0));
  EXPECT_EQ(box(Effect::delay, "delay"), std::pair(-10.0 / 10, 10.0 / 10));
  EXPECT_EQ(box(Effect::position_dependence, "amplitude"), std::pair(-0.9 * 2.0, 0.9 * 2.0));
}

TEST(EffectTable, AmbiguousPairsAreMutualAndNameTheSameExcitation) {
  // methods.md 7: offset/asymmetry, inertia/position-dependence, delay/frictional-lag.
  for (Effect e : kAllEffects) {
    const auto partner = effect_info(e).partner;
    if (!partner) continue;
    ASSERT_TRUE(effect_info(*partner).partner.has_value()) << effect_info(e).name;
    EXPECT_EQ(*effect_info(*partner).partner, e) << effect_info(e).name;
    EXPECT_EQ(effect_info(*partner).separating_excitation, effect_info(e).separating_excitation);
    EXPECT_FALSE(effect_info(e).separating_excitation.empty());
  }
  EXPECT_EQ(effect_info(Effect::offset).partner, Effect::asymmetry);
  EXPECT_EQ(effect_info(Effect::inertia).partner, Effect::position_dependence);
  EXPECT_EQ(effect_info(Effect::delay).partner, Effect::frictional_lag);
}

TEST(EffectTable, EvidenceOrderListsEveryEffectOnce) {
  std::vector<Effect> order(friction::kEvidenceOrder.begin(), friction::kEvidenceOrder.end());
  std::vector<Effect> all(kAllEffects.begin(), kAllEffects.end());
  std::sort(order.begin(), order.end());
  EXPECT_EQ(order, all);
}

TEST(EffectTable, StribeckStartGridSpansTheSlidingSpeeds) {
  // 101 speeds 0, 1e-5, ..., 1e-3 m/s: quantiles 2..75 %, then 8 points from the 95 % quantile
  // down by a factor 100.
  std::vector<double> speeds;
  for (int k = 100; k >= 0; --k) speeds.push_back(1e-5 * k);
  const std::vector<double> grid = friction::stribeck_start_grid(speeds);
  ASSERT_EQ(grid.size(), 13u);
  EXPECT_DOUBLE_EQ(grid[0], 2e-5);
  EXPECT_DOUBLE_EQ(grid[3], 50e-5);
  EXPECT_DOUBLE_EQ(grid[5], 95e-5);
  EXPECT_NEAR(grid[12], 95e-7, 1e-18);
  for (std::size_t k = 6; k < grid.size(); ++k) EXPECT_LT(grid[k], grid[k - 1]);
  EXPECT_TRUE(friction::stribeck_start_grid({}).empty());
}

TEST(EffectTable, LagStartedWithoutAVelocityPieceBringsAViscousCompanion) {
  friction::EvidenceStartContext c;
  c.reference_force = 2.0;
  c.duration = 4.0;
  c.sample_period = 1e-3;
  c.sliding_speed_max = 1e-3;
  const friction::EffectStart w{-0.5, 0, 0, 0, 0};
  const auto alone = friction::start_from_evidence(Effect::frictional_lag, &w, c);
  ASSERT_TRUE(alone.viscous_companion.has_value());
  EXPECT_DOUBLE_EQ(*alone.viscous_companion, 0.05 * 2.0 / 1e-3);  // no viscous evidence
  EXPECT_DOUBLE_EQ(alone.values[0], 0.5 / 100.0);                 // -coef / sigma2
  c.has_velocity_piece = true;
  c.current_viscous = 50.0;
  const auto with = friction::start_from_evidence(Effect::frictional_lag, &w, c);
  EXPECT_FALSE(with.viscous_companion.has_value());
  EXPECT_DOUBLE_EQ(with.values[0], 0.5 / 50.0);
}

}  // namespace
}  // namespace test_effect_table
