// The HTML reports (report.hpp, report_pages.hpp, --report): thinning that keeps what a pixel
// shows, axes with units, escaping, self-contained files written atomically, and sizes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "friction/error.hpp"
#include "friction/report.hpp"
#include "friction/report_pages.hpp"
#include "report_fixtures.hpp"
#include "support/cli_runner.hpp"

namespace test_report {
namespace {

using namespace friction::report;
using friction::Record;
using friction::testing::read_text;
using friction::testing::run_cli;
using friction::testing::TempDir;

std::size_t marks(const Runs& runs) {
  std::size_t n = 0;
  for (const auto& r : runs) n += r.size();
  return n;
}

std::vector<std::size_t> flatten(const Runs& runs) {
  std::vector<std::size_t> v;
  for (const auto& r : runs) v.insert(v.end(), r.begin(), r.end());
  return v;
}

// ---- thinning ------------------------------------------------------------------------------

TEST(ReportThinning, AOneSampleSpikeIn100kSamplesSurvivesTheColumnReduction) {
  const std::size_t n = 100000, spike = 54321;
  std::vector<double> px(n), py(n);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (std::size_t k = 0; k < n; ++k) {
    px[k] = 80.0 + 860.0 * static_cast<double>(k) / static_cast<double>(n);
    py[k] = 200.0 + 50.0 * std::sin(static_cast<double>(k) * 1e-4) + noise(rng);
  }
  py[spike] = 20.0;       // one sample far above the rest (SVG y grows downwards)
  py[spike + 7] = 390.0;  // and one far below, in the same column
  const Runs runs = thin_columns(px, py);
  const auto kept = flatten(runs);
  EXPECT_TRUE(std::binary_search(kept.begin(), kept.end(), spike));
  EXPECT_TRUE(std::binary_search(kept.begin(), kept.end(), spike + 7));
  // At most four samples per pixel column, in time order.
  EXPECT_LE(kept.size(), 4u * 861u);
  EXPECT_GT(kept.size(), 2u * 860u);
  EXPECT_TRUE(std::is_sorted(kept.begin(), kept.end()));
  // The envelope of every column is kept exactly: its extremes are among the kept samples.
  for (std::size_t c = 80; c < 940; c += 37) {
    double lo = 1e300, hi = -1e300, klo = 1e300, khi = -1e300;
    for (std::size_t k = 0; k < n; ++k)
      if (std::floor(px[k]) == static_cast<double>(c))
        lo = std::min(lo, py[k]), hi = std::max(hi, py[k]);
    for (const std::size_t k : kept)
      if (std::floor(px[k]) == static_cast<double>(c))
        klo = std::min(klo, py[k]), khi = std::max(khi, py[k]);
    EXPECT_EQ(lo, klo) << "column " << c;
    EXPECT_EQ(hi, khi) << "column " << c;
  }
}

TEST(ReportThinning, TheSpikeSurvivesIntoTheRenderedSvg) {
  const std::size_t n = 100000;
  std::vector<double> t(n), f(n);
  for (std::size_t k = 0; k < n; ++k) t[k] = 1e-4 * static_cast<double>(k), f[k] = std::sin(t[k]);
  f[77777] = 25.0;  // the only sample above 1
  Figure fig;
  fig.id = "spike";
  fig.x = {"time", "s"};
  fig.panels = {
      Panel{"force", {"force", "N"}, {{"measured", Role::measured, Mark::line, t, f}}, 200}};
  const std::string svg = render_figure(fig);
  // The y axis reaches the spike: a tick label of 20 or more exists, and the path goes to the top
  // of the plot area (y = 30 + 4 % padding of 200 = 37.3 within rounding).
  EXPECT_NE(svg.find(">20<"), std::string::npos);
  double top = 1e9;
  const std::size_t d = svg.find(" d=\"M");
  ASSERT_NE(d, std::string::npos);
  std::istringstream path(svg.substr(d + 4, svg.find('"', d + 4) - d - 4));
  char command;
  double x, y;
  while (path >> command >> x >> y) top = std::min(top, y);
  EXPECT_NEAR(top, 30.0 + 200.0 * 0.04 / 1.08, 0.2);
}

TEST(ReportThinning, PerCellThinningBoundsTheMarksOfAScatterPlot) {
  const std::size_t n = 100000;
  std::vector<double> px(n), py(n);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t k = 0; k < n; ++k) px[k] = 200.0 * u(rng), py[k] = 100.0 * u(rng);
  const double cell = 2.0;
  const Runs runs = thin_points(px, py, cell);
  const auto kept = flatten(runs);
  EXPECT_LE(kept.size(), 100u * 50u);  // at most one mark per 2 x 2 cell
  // Every occupied cell keeps exactly one mark.
  std::set<std::pair<long, long>> occupied, shown;
  for (std::size_t k = 0; k < n; ++k)
    occupied.insert({static_cast<long>(px[k] / cell), static_cast<long>(py[k] / cell)});
  for (const std::size_t k : kept)
    shown.insert({static_cast<long>(px[k] / cell), static_cast<long>(py[k] / cell)});
  EXPECT_EQ(shown, occupied);
  EXPECT_EQ(shown.size(), kept.size());
}

TEST(ReportThinning, ALoopTracedManyTimesCostsWhatItsCellsCostAndKeepsEveryCellStep) {
  // A hysteresis-like loop with bounded noise (so that the cells it can occupy are bounded)
  // traced 100 times (100k samples) and 1000 times.
  const auto loop = [](std::size_t cycles) {
    const std::size_t per = 1000;
    std::vector<double> px, py;
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> noise(-0.7, 0.7);
    for (std::size_t c = 0; c < cycles; ++c)
      for (std::size_t k = 0; k < per; ++k) {
        const double a = 2 * M_PI * static_cast<double>(k) / per;
        px.push_back(240 + 200 * std::cos(a) + noise(rng));
        py.push_back(150 + 100 * std::tanh(3 * std::sin(a + 0.6)) + noise(rng));
      }
    return std::make_pair(px, py);
  };
  const double cell = 2.0;
  const auto key = [&](double x, double y) {
    return std::make_pair(static_cast<long>(std::floor(x / cell)),
                          static_cast<long>(std::floor(y / cell)));
  };
  const auto [x100, y100] = loop(100);
  const auto [x1000, y1000] = loop(1000);
  const Runs r100 = thin_polyline(x100, y100, cell), r1000 = thin_polyline(x1000, y1000, cell);
  std::set<std::pair<long, long>> cells;
  for (std::size_t k = 0; k < x100.size(); ++k) cells.insert(key(x100[k], y100[k]));
  // Bounded by the cells the path occupies (a cell has 8 neighbours: 4 steps per cell, and a
  // vertex per step at most), not by the samples: ten times the samples add less than a third.
  EXPECT_LE(marks(r100), 4 * cells.size() + r100.size());
  std::set<std::pair<long, long>> cells1000;
  for (std::size_t k = 0; k < x1000.size(); ++k) cells1000.insert(key(x1000[k], y1000[k]));
  EXPECT_LE(marks(r1000), 4 * cells1000.size() + r1000.size());
  EXPECT_LT(marks(r100), x100.size() / 20);
  EXPECT_LT(static_cast<double>(marks(r1000)), 1.3 * static_cast<double>(marks(r100)));
  // Every step between two cells that the record takes is drawn, and no other.
  using Step = std::pair<std::pair<long, long>, std::pair<long, long>>;
  std::set<Step> taken, drawn;
  auto previous = key(x100[0], y100[0]);
  for (std::size_t k = 1; k < x100.size(); ++k) {
    const auto c = key(x100[k], y100[k]);
    if (c != previous) taken.insert(std::minmax(previous, c));
    previous = c;
  }
  for (const auto& run : r100)
    for (std::size_t j = 1; j < run.size(); ++j)
      drawn.insert(
          std::minmax(key(x100[run[j - 1]], y100[run[j - 1]]), key(x100[run[j]], y100[run[j]])));
  EXPECT_EQ(drawn, taken);
}

TEST(ReportThinning, NonFiniteSamplesBreakTheLineAndAreNeverDrawn) {
  std::vector<double> px{0.5, 1.5, 2.5, 3.5, 4.5}, py{1, 2, NAN, 4, 5};
  const Runs runs = thin_columns(px, py);
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0], (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(runs[1], (std::vector<std::size_t>{3, 4}));
  EXPECT_EQ(marks(thin_points(px, py, 1.0)), 4u);
}

// ---- axes, units, escaping -------------------------------------------------------------------

TEST(ReportAxes, DisplayUnitsAndTicksReadWell) {
  EXPECT_EQ(display_unit("m", 4.4e-5).unit, "\u00b5m");
  EXPECT_DOUBLE_EQ(display_unit("m", 4.4e-5).factor, 1e6);
  EXPECT_EQ(display_unit("m/s", 3e-3).unit, "mm/s");
  EXPECT_EQ(display_unit("s", 250.0).unit, "s");  // no kiloseconds
  EXPECT_EQ(display_unit("N", 2.0).unit, "N");
  EXPECT_EQ(display_unit("%", 1e-3).unit, "%");
  EXPECT_EQ(format_quantity(4.44e-5, "m"), "44.4 \u00b5m");
  for (const auto& [lo, hi] : std::vector<std::pair<double, double>>{
           {-0.31, 0.31}, {0, 12.1}, {-2.1, 2.1}, {1e-7, 3e-7}, {237e-6, 265e-6}}) {
    const auto t = nice_ticks(lo, hi, 3);
    EXPECT_GE(t.size(), 2u) << lo << " " << hi;
    EXPECT_LE(t.size(), 5u) << lo << " " << hi;
    for (const double v : t) EXPECT_TRUE(v >= lo - 1e-12 && v <= hi + 1e-12);
  }
}

// Every <svg class="plot"> of a page, with its axis labels.
struct PlotLabels {
  std::string id;
  std::vector<std::string> x, y;
};
// (Plain string search: std::regex trips GCC 12's -Wmaybe-uninitialized under the sanitizers.)
std::vector<PlotLabels> plot_labels(const std::string& html) {
  std::vector<PlotLabels> plots;
  const std::string open = "<svg class=\"plot\" id=\"";
  for (std::size_t at = html.find(open); at != std::string::npos; at = html.find(open, at + 1)) {
    const std::size_t id = at + open.size();
    PlotLabels p{html.substr(id, html.find('"', id) - id), {}, {}};
    const std::size_t end = html.find("</svg>", at);
    const std::string label = "<text class=\"axis-label ";
    for (std::size_t l = html.find(label, at); l < end; l = html.find(label, l + 1)) {
      const char axis = html[l + label.size()];
      const std::size_t text = html.find('>', l) + 1;
      (axis == 'x' ? p.x : p.y).push_back(html.substr(text, html.find('<', text) - text));
    }
    plots.push_back(std::move(p));
  }
  return plots;
}

// "quantity [unit]": a non-empty quantity, then a non-empty unit in brackets.
bool has_unit(const std::string& label) {
  const std::size_t open = label.find('['), close = label.find(']', open);
  return open != std::string::npos && open > 0 && close != std::string::npos && close > open + 1 &&
         label.find_first_not_of(' ') < open;
}

void expect_every_plot_has_axes_with_units(const std::string& html, std::size_t at_least) {
  const auto plots = plot_labels(html);
  EXPECT_GE(plots.size(), at_least);
  for (const auto& p : plots) {
    ASSERT_FALSE(p.x.empty()) << p.id << " has no x-axis label";
    for (const auto& l : p.x) EXPECT_TRUE(has_unit(l)) << p.id << ": " << l;
    // Bar charts label their rows by category; every other plot has a y quantity per panel.
    if (p.id.find("errors") == std::string::npos) {
      ASSERT_FALSE(p.y.empty()) << p.id << " has no y-axis label";
      for (const auto& l : p.y) EXPECT_TRUE(has_unit(l)) << p.id << ": " << l;
    }
  }
}

TEST(ReportAxes, EveryPlotOfACompareReportHasAxisLabelsWithUnits) {
  Record est, val;
  const std::string html = friction::testing::synthetic_compare_report(6000, est, val).html();
  expect_every_plot_has_axes_with_units(html, 1 + 2 * 3 * 5);
}

TEST(ReportHtml, TextIsEscapedEverywhere) {
  const std::string evil = "<script>alert('x')</script> & \"q\"";
  Document doc(evil);
  doc.summary(evil);
  doc.section("s", evil);
  doc.paragraph(evil);
  doc.list("warnings", {evil});
  doc.preformatted(evil);
  Table t;
  t.caption = evil;
  t.header = {evil};
  t.rows = {{evil}};
  doc.add(t);
  std::vector<double> x{0, 1, 2}, y{1, 2, 3};
  Figure f;
  f.id = "a\"b<c";
  f.kind = evil;
  f.title = evil;
  f.caption = evil;
  f.x = {evil, "s"};
  f.panels = {Panel{evil, {evil, "N"}, {{evil, Role::measured, Mark::line, x, y}}, 100}};
  doc.add(f);
  const std::string html = doc.html();
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("alert('x')"), std::string::npos);
  EXPECT_EQ(html.find("\"q\""), std::string::npos);
  EXPECT_NE(html.find("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;q&quot;"),
            std::string::npos);
  EXPECT_NE(html.find("id=\"a-b-c\""), std::string::npos);  // ids are made safe, not escaped
  EXPECT_EQ(escape_html("a<b>&'\""), "a&lt;b&gt;&amp;&#39;&quot;");
}

// ---- files -----------------------------------------------------------------------------------

// Nothing in a report may be fetched: no URL, no script, no external resource.
void expect_self_contained(const std::string& html) {
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(html.find("http://"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("<link"), std::string::npos);
  EXPECT_EQ(html.find("<img"), std::string::npos);
  EXPECT_EQ(html.find("src="), std::string::npos);
  EXPECT_EQ(html.find("href="), std::string::npos);
  EXPECT_EQ(html.find("@import"), std::string::npos);
  EXPECT_EQ(html.find("url(http"), std::string::npos);
  EXPECT_NE(html.find("default-src 'none'"), std::string::npos);
  EXPECT_NE(html.find("</html>"), std::string::npos);
}

TEST(ReportFiles, AReportIsWrittenAtomicallyAndIsSelfContained) {
  TempDir dir;
  Record est, val;
  const Document doc = friction::testing::synthetic_compare_report(4000, est, val);
  const std::string path = dir.file("r.html");
  friction::testing::write_text(path, "old");
  write_report(path, doc);
  const std::string html = read_text(path);
  EXPECT_EQ(html, doc.html());
  expect_self_contained(html);
  // Only the report is in the directory: the temporary file was renamed over the target.
  std::size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) ++files, (void)e;
  EXPECT_EQ(files, 1u);
  // A directory that does not exist: an error, and nothing is written anywhere.
  EXPECT_THROW(write_report(dir.file("missing/r.html"), doc), friction::Error);
  EXPECT_FALSE(std::filesystem::exists(dir.file("missing")));
}

TEST(ReportFiles, A100kSampleCompareReportStaysUnder3MB) {
  Record est, val;
  const std::string html = friction::testing::synthetic_compare_report(100000, est, val).html();
  ASSERT_EQ(est.size(), 100000u);
  ASSERT_EQ(val.size(), 100000u);
  RecordProperty("bytes", std::to_string(html.size()));
  EXPECT_LT(html.size(), 3u * 1000u * 1000u);
  expect_self_contained(html);
  expect_every_plot_has_axes_with_units(html, 1 + 2 * 3 * 5);
}

TEST(ReportFiles, A100kSampleDiagnoseReportWithFindingPanelsStaysUnder3MB) {
  const Record est = friction::testing::synthetic_report_record(100000, 1, "est.csv");
  const Record val = friction::testing::synthetic_report_record(100000, 2, "val.csv");
  DiagnoseFits fits;
  fits.baseline_estimation = friction::testing::reference_run("lugre", est);
  fits.baseline_validation = friction::testing::reference_run("lugre", val);
  fits.final_estimation = friction::testing::reference_run("gms", est);
  fits.final_validation = friction::testing::reference_run("gms", val);
  nlohmann::json doc = {{"command", "diagnose"}, {"warnings", nlohmann::json::array()}};
  doc["baseline"] = {{"model", {{"type", "lugre"}}}, {"validation", {{"rss_sss_percent", 1.0}}}};
  doc["final"] = {{"model", {{"type", "maxwell-slip"}}},
                  {"validation", {{"rss_sss_percent", 0.1}}}};
  const char* effects[] = {
      "viscous", "stribeck", "frictional-lag", "offset",          "position-dependence",
      "drift",   "inertia",  "delay",          "nonlocal-memory", "normal-load"};
  std::vector<FindingPanelInput> panels;
  for (const char* e : effects) {
    doc["findings"].push_back({{"effect", e},
                               {"validation_before", 1.0},
                               {"validation_after", 0.1},
                               {"parameters", {{"viscous", 40.0}}},
                               {"ambiguous_with", {"offset"}},
                               {"separating_excitation", "strokes at several speeds"}});
    panels.push_back({e, &val, fits.baseline_validation, fits.final_validation, "baseline", "final",
                      doc["findings"].back()});
  }
  doc["candidates"] = {{{"effect", "offset"},
                        {"estimation_rss_sss_percent", 0.5},
                        {"validation_rss_sss_percent", nullptr},
                        {"delta_bic", 3.0},
                        {"extra_parameters", 1},
                        {"earns_place", false},
                        {"verdict", "BIC does not fall"}}};
  const std::string html =
      diagnose_report(doc, est, val, fits, panels, {"friction-identify diagnose", "test"}).html();
  RecordProperty("bytes", std::to_string(html.size()));
  EXPECT_LT(html.size(), 3u * 1000u * 1000u);
  expect_self_contained(html);
  expect_every_plot_has_axes_with_units(html, 10 + 2 * 7);
  // One signature plot per finding, and the candidate that did not earn its place.
  EXPECT_EQ(plot_labels(html).size(), std::size(effects) + 2u * 7u);
  EXPECT_NE(html.find("BIC does not fall"), std::string::npos);
  EXPECT_NE(html.find("Ambiguous with offset"), std::string::npos);
}

TEST(ReportFiles, AFindingPanelRefusesForcesOfTheWrongLength) {
  const Record val = friction::testing::synthetic_report_record(2000, 2, "val.csv");
  const RecordView view = view_record(val, "validation");
  std::vector<double> short_run(val.size() - 1, 0.0), run(val.size(), 0.0);
  Document doc("t");
  EXPECT_THROW(
      add_finding_panel(doc, "f", view, {"viscous", &val, short_run, run, "before", "after", {}}),
      friction::InvalidParameter);
}

TEST(ReportView, SlidingAndTheZoomComeFromTheRecord) {
  const Record r = friction::testing::synthetic_report_record(20000, 3, "r.csv");
  const RecordView v = view_record(r, "estimation");
  // The combined excitation: strokes, then presliding loops; the zoom is on the loops, where
  // nothing slides.
  EXPECT_GT(v.presliding_travel, 0.0);
  EXPECT_LT(v.presliding_travel, 1e-4);
  std::size_t sliding_in_zoom = 0, sliding = 0, in_zoom = 0;
  for (std::size_t k = 0; k < r.size(); ++k) {
    sliding += v.sliding[k];
    if (r.time[k] >= v.zoom_lo && r.time[k] <= v.zoom_hi)
      ++in_zoom, sliding_in_zoom += v.sliding[k];
  }
  EXPECT_GT(sliding, r.size() / 5);
  // (The zoom starts a little before the first presliding reversal: the end of a stroke.)
  EXPECT_LT(sliding_in_zoom, in_zoom / 20);
  EXPECT_GT(v.zoom_lo, r.time.front() + 0.3 * (r.time.back() - r.time.front()));
  EXPECT_NE(v.zoom_what.find("presliding reversals"), std::string::npos);
}

// ---- the command line --------------------------------------------------------------------------

TEST(ReportCli, ValidateWritesAReportAndABadReportPathWritesNothing) {
  TempDir dir;
  const std::string rec = dir.file("r.csv"), truth = dir.file("t.json");
  ASSERT_EQ(run_cli("generate --stroke 0.2e-3 --speeds 1e-3,4e-3 --cycles 3 --noise 0.01 --out " +
                    rec + " --truth " + truth)
                .status,
            0);
  const auto ok = run_cli("validate --model-file " + truth + " --data " + rec + " --report " +
                          dir.file("v.html") + " --format json --out " + dir.file("v.json"));
  ASSERT_EQ(ok.status, 0) << ok.err;
  const std::string html = read_text(dir.file("v.html"));
  expect_self_contained(html);
  EXPECT_NE(html.find("id=\"validation-time\""), std::string::npos);
  EXPECT_NE(html.find("id=\"validation-loops\""), std::string::npos);
  EXPECT_NE(html.find("id=\"validation-sliding\""), std::string::npos);
  EXPECT_NE(html.find("friction-identify validate --model-file"), std::string::npos);
  // The JSON document is what it was without --report.
  const auto plain = run_cli("validate --model-file " + truth + " --data " + rec +
                             " --format json --out " + dir.file("plain.json"));
  ASSERT_EQ(plain.status, 0);
  auto a = nlohmann::json::parse(read_text(dir.file("v.json")));
  auto b = nlohmann::json::parse(read_text(dir.file("plain.json")));
  EXPECT_EQ(a, b);

  // A report into a directory that does not exist: bad usage, one line, and no output at all.
  const auto bad = run_cli("validate --model-file " + truth + " --data " + rec + " --report " +
                           dir.file("nowhere/v.html") + " --out " + dir.file("bad.json"));
  EXPECT_EQ(bad.status, 2);
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_NE(bad.err.find("does not exist"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir.file("bad.json")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("nowhere")));
}

}  // namespace
}  // namespace test_report
