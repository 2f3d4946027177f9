// covariance_report.hpp: standard errors and intervals in the parametrisation each parameter is
// fitted in, correlations, and the identifiability warnings every method words.
#include <gtest/gtest.h>

#include <Eigen/Core>

#include <cmath>

#include "friction/covariance_report.hpp"

namespace test_covariance_report {
namespace {

using friction::CovarianceParameter;
using friction::IdentifiabilityIssue;
using friction::Parametrisation;

TEST(CovarianceReport, LogFittedParametersGetLogNormalIntervals) {
  Eigen::MatrixXd c(2, 2);
  c << 0.04, 0.012, 0.012, 0.09;  // s = 0.2 and 0.3 in the fitted coordinates, r = 0.2
  const std::vector<CovarianceParameter> p{
      {"stiffness[1]", "N/m", 1e4, Parametrisation::log, 1.0, 0},
      {"offset", "N", 0.05, Parametrisation::linear, 2.0, 1}};
  const auto r = friction::covariance_report(&c, p);
  ASSERT_TRUE(r.computed);
  EXPECT_DOUBLE_EQ(r.parameters[0].standard_error, 1e4 * 0.2);
  EXPECT_DOUBLE_EQ(r.parameters[0].lower95, 1e4 * std::exp(-1.96 * 0.2));
  EXPECT_DOUBLE_EQ(r.parameters[0].upper95, 1e4 * std::exp(1.96 * 0.2));
  // Linear: the reported value is `scale` times the fitted one, so is its standard error.
  EXPECT_DOUBLE_EQ(r.parameters[1].standard_error, 0.3 * 2.0);
  EXPECT_DOUBLE_EQ(r.parameters[1].lower95, 0.05 - 1.96 * 0.6);
  EXPECT_DOUBLE_EQ(r.parameters[1].upper95, 0.05 + 1.96 * 0.6);
  EXPECT_DOUBLE_EQ(r.correlation(0, 1), 0.012 / std::sqrt(0.04 * 0.09));
  EXPECT_EQ(r.correlation(0, 0), 1.0);
  EXPECT_TRUE(r.warnings.empty());
}

TEST(CovarianceReport, WarnsOfWideIntervalsInsignificanceCorrelationAndMissingErrors) {
  Eigen::MatrixXd c(3, 3);
  c << 1.0, 0.995, 0.0, 0.995, 1.0, 0.0, 0.0, 0.0, 1.0;
  std::vector<CovarianceParameter> p{
      {"threshold[1]", "m", 1e-6, Parametrisation::log, 1.0, 0},         // e^(3.92) > 10: wide
      {"input_filter[0]", "N/m", 1.0, Parametrisation::linear, 1.0, 1},  // |1| < 1.96: n.s.
      {"mass", "kg", 0.0, Parametrisation::linear, 1.0, -1, true},       // at a bound
      {"held", "N", 3.0, Parametrisation::linear, 1.0, -1}};
  friction::CovarianceOptions o;
  o.zero_test = true;
  o.correlation_limit = 0.99;
  const auto r = friction::covariance_report(&c, p, o);
  ASSERT_EQ(r.warnings.size(), 5u);
  EXPECT_EQ(r.warnings[0].issue, IdentifiabilityIssue::wide_interval);
  EXPECT_EQ(r.warnings[1].issue, IdentifiabilityIssue::not_significant);
  EXPECT_EQ(r.warnings[2].issue, IdentifiabilityIssue::at_bound);
  EXPECT_EQ(r.warnings[3].issue, IdentifiabilityIssue::no_standard_error);
  EXPECT_EQ(r.warnings[4].issue, IdentifiabilityIssue::correlated);
  EXPECT_EQ(r.warnings[4].other, 1u);
  // Without a standard error: 0, and the interval collapses to the value (never NaN).
  EXPECT_EQ(r.parameters[3].standard_error, 0.0);
  EXPECT_EQ(r.parameters[3].lower95, 3.0);
  EXPECT_EQ(r.parameters[3].upper95, 3.0);
  EXPECT_EQ(r.correlation(0, 3), 0.0);
}

TEST(CovarianceReport, ClipsToTheSearchBoxAndSaysSo) {
  Eigen::MatrixXd c(1, 1);
  c << 400.0;  // s = 20: e^(39.2) overflows any box
  const std::vector<CovarianceParameter> p{
      {"micro_damping", "N s/m", 1.0, Parametrisation::log, 1.0, 0, false, 0.03, 900.0}};
  friction::CovarianceOptions o;
  o.clip_to_limits = true;
  const auto r = friction::covariance_report(&c, p, o);
  EXPECT_TRUE(r.parameters[0].clipped);
  EXPECT_EQ(r.parameters[0].lower95, 0.03);
  EXPECT_EQ(r.parameters[0].upper95, 900.0);
}

TEST(CovarianceReport, NoCovarianceGivesNoErrorsAndOneWarning) {
  const std::vector<CovarianceParameter> p{{"a", "", 2.0}, {"b", "", -1.0}};
  const auto r = friction::covariance_report(nullptr, p);
  EXPECT_FALSE(r.computed);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_EQ(r.warnings[0].issue, IdentifiabilityIssue::covariance_unavailable);
  for (std::size_t a = 0; a < 2; ++a) {
    EXPECT_EQ(r.parameters[a].standard_error, 0.0);
    EXPECT_EQ(r.parameters[a].lower95, p[a].value);
  }
  EXPECT_TRUE(r.correlation.isIdentity());
}

}  // namespace
}  // namespace test_covariance_report
