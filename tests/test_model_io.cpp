// Saved models: every type, with extensions, survives JSON and simulates the same afterwards.
#include <gtest/gtest.h>

#include <cmath>

#include "friction/excitation.hpp"
#include "friction/model_io.hpp"

namespace test_model_io {
namespace {

using friction::AnyModel;
using friction::Json;

friction::Record short_record() {
  friction::ExcitationOptions e;
  e.stroke = 0.2e-3;
  e.speeds = {1e-3, 4e-3};
  e.presliding_cycles = 3;
  const auto s = friction::make_excitation(e);
  friction::Record r;
  r.time = s.time;
  r.displacement = s.displacement;
  for (double t : r.time) r.normal.push_back(10.0 + std::sin(t));
  return r;
}

TEST(ModelIo, EveryTypeWithExtensionsRoundTripsThroughJson) {
  const auto record = short_record();
  for (const char* type : friction::kModelTypes) {
    SCOPED_TRACE(type);
    AnyModel model = friction::reference_model(type, 1000.0);
    auto ext = model.extensions();
    friction::parse_effect("viscous=20", ext);
    friction::parse_effect("asymmetry=0.1", ext);
    friction::parse_effect("position-dependence=0.1,wavelength=1e-4", ext);
    friction::parse_effect("normal-load=0.15", ext);
    friction::parse_effect("delay=0.002", ext);
    model = model.with_extensions(ext);
    const Json saved = model.to_json();
    EXPECT_EQ(saved["type"], type);
    EXPECT_EQ(saved["extensions"]["position-dependence"]["wavelength"], 1e-4);
    // Through text, as a file would carry it.
    AnyModel loaded = AnyModel::from_json(Json::parse(saved.dump()), "mem");
    EXPECT_EQ(loaded.to_json(), saved);
    EXPECT_EQ(loaded.parameter_count(), model.parameter_count());
    const auto a = model.simulate(record);
    const auto b = loaded.simulate(record);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) ASSERT_EQ(a[k], b[k]);
  }
}

TEST(ModelIo, AcceptsADocumentWithTheModelInside) {
  Json doc;
  doc["schema_version"] = 1;
  doc["model"] = friction::reference_model("lugre", 1000.0).to_json();
  EXPECT_EQ(AnyModel::from_json(doc).type(), "lugre");
}

TEST(ModelIo, RejectsMalformedDocumentsWithAClearMessage) {
  const auto expect_error = [](const std::string& text, const std::string& needle) {
    try {
      AnyModel::from_json(Json::parse(text), "m.json");
      ADD_FAILURE() << "accepted " << text;
    } catch (const friction::Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error(R"({"parameters": {}})", "type");
  expect_error(R"({"type": "coulomb", "parameters": {}})", "unknown type");
  expect_error(R"({"type": "maxwell-slip", "parameters": {"stiffness": [1]}})", "threshold");
  expect_error(R"({"type": "maxwell-slip", "parameters": {"stiffness": [1], "threshold": ["a"]}})",
               "numbers");
  expect_error(R"({"type": "maxwell-slip", "parameters": {"stiffness": [1], "threshold": [-1]}})",
               "threshold");
  expect_error(R"({"type": "static", "parameters": {"coulomb": 1}, "extensions": {"sticky": {}}})",
               "unknown effect");
  expect_error(
      R"({"type": "static", "parameters": {"coulomb": 1}, "extensions": {"viscous": {"mass": 1}}})",
      "unknown parameter");
}

TEST(ModelIo, EffectSpecificationsSetTheNamedParameters) {
  friction::ExtensionParameters<double> ext;
  friction::parse_effect("stribeck=2.2,stribeck_velocity=5e-4,stribeck_exponent=1.5", ext);
  ASSERT_TRUE(ext.stribeck);
  EXPECT_EQ(ext.stribeck->static_force, 2.2);
  EXPECT_EQ(ext.stribeck->stribeck_velocity, 5e-4);
  EXPECT_EQ(ext.stribeck->stribeck_exponent, 1.5);
  friction::parse_effect("inertia=0.5", ext);
  EXPECT_EQ(ext.inertia->mass, 0.5);
  EXPECT_THROW(friction::parse_effect("inertia", ext), friction::InvalidParameter);
  EXPECT_THROW(friction::parse_effect("inertia=x", ext), friction::InvalidParameter);
  EXPECT_THROW(friction::parse_effect("inertia=1,wavelength=2", ext), friction::InvalidParameter);
  EXPECT_THROW(friction::parse_effect("inertia=-1", ext), friction::InvalidParameter);
}

}  // namespace
}  // namespace test_model_io
