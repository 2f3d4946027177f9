// Self-contained HTML reports with inline SVG plots: what a person looks at after a run.
//
// Why inline SVG and no JavaScript.  A report is read on a laptop, mailed, archived and printed,
// often where there is no network.  SVG written by the tool needs no plotting library, renders the
// same in every browser and in print (vector, sharp at any zoom), and a page without scripts has
// nothing to fail at load time.  The document carries a Content-Security-Policy that forbids every
// fetch (default-src 'none'), so a reference to anything outside the file could not load even if
// one slipped in; the browser check (scripts/check-report.py) fails on the console error it raises.
//
// Thinning.  A record of 100k samples drawn point by point would make a file of several MB and a
// plot no more informative than one that keeps what a pixel can show:
//   * time series (x non-decreasing): per pixel column, the first, the last, the smallest and the
//     largest sample, in their order (the "M4" reduction of Jugel et al., VLDB 2014).  The line
//     drawn through them covers exactly the pixels the full line covers, so a one-sample spike
//     survives however long the record;
//   * scatter plots: the first sample in each cell of `cell` x `cell` pixels; the number of marks
//   is
//     bounded by the number of cells, whatever the number of samples;
//   * loops (force against displacement, connected in time order): a segment between two cells is
//     drawn once.  A presliding loop traced fifty times costs what one costs, and the path still
//     joins every pair of neighbouring cells the record joins.
//
// Colours.  One colour per meaning, the same in every report, from the palette of Okabe & Ito
// (2008), which stays distinguishable under the common colour-vision deficiencies and in
// grey-scale print (the measured force is black, everything else a hue).  Role::residual
// (vermillion) and Role::before (orange) are the closest pair; no view draws both: a view of one
// model shows measured/simulated/residual, a view of two shows measured/before/after.
//
// Units.  Axes take SI quantities and pick a display prefix so that tick labels read 0.5, 1, 2
// rather than 5e-07 (displacement [um], velocity [mm/s]); every axis label names its unit.
#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace friction::report {

/// What a colour means (see the header comment).
enum class Role { measured, simulated, residual, before, after, estimation, validation, reference };

struct RoleStyle {
  std::string_view name;    ///< what the legend says by default
  std::string_view colour;  ///< #rrggbb
};
RoleStyle role_style(Role role);

/// Text for HTML (element content and attribute values): & < > " ' escaped.
std::string escape_html(std::string_view text);

/// A number for people: `precision` significant digits, no trailing zeros.
std::string format_number(double value, int precision = 4);

/// The unit an axis shows and the factor from SI to it.
struct DisplayUnit {
  double factor = 1;  ///< displayed value = SI value * factor
  std::string unit;   ///< e.g. "mm/s"
};
/// A metric prefix for `si_unit` (m, N, s, m/s, m/s^2, N/m, kg) chosen so that `magnitude` (the
/// largest absolute value shown) displays between 1 and 1000; other units unchanged.
DisplayUnit display_unit(std::string_view si_unit, double magnitude);

/// A value with its unit, prefixed for reading: format_quantity(4.44e-5, "m") = "44.4 um".
std::string format_quantity(double value, std::string_view si_unit, int precision = 3);

/// Round tick values covering [lo, hi] (steps 1, 2 or 5 times a power of ten), about `target`.
std::vector<double> nice_ticks(double lo, double hi, int target = 6);

/// Runs of indices to draw (a run is broken where a sample is not finite).
using Runs = std::vector<std::vector<std::size_t>>;

/// Min/max per pixel column: px, py are pixel coordinates (px non-decreasing for a time series;
/// columns are floor(px)).  Keeps per column the first, smallest, largest and last sample.
Runs thin_columns(std::span<const double> px, std::span<const double> py);

/// Per pixel cell, for scatter plots: the first sample in each `cell` x `cell` square.  One run.
Runs thin_points(std::span<const double> px, std::span<const double> py, double cell);

/// Per pixel cell, for loops: a segment between two cells is kept the first time the path takes it.
Runs thin_polyline(std::span<const double> px, std::span<const double> py, double cell);

/// An axis: a quantity in SI units.
struct Axis {
  Axis() = default;
  Axis(std::string quantity_, std::string unit_)
      : quantity(std::move(quantity_)), unit(std::move(unit_)) {}
  std::string quantity;          ///< e.g. "force"
  std::string unit;              ///< SI: "N", "m", "s", "m/s", "m/s^2", "%", "" (dimensionless)
  std::optional<double> lo, hi;  ///< a fixed range (SI); otherwise from the data
  bool symmetric = false;        ///< a range symmetric about zero (residuals), with a zero line
  bool log = false;              ///< logarithmic (bar charts only)
};

enum class Mark {
  line,      ///< a time series (thin_columns)
  polyline,  ///< a loop in time order (thin_polyline)
  points     ///< a scatter plot (thin_points)
};

/// One thing drawn.  The spans must outlive the call that renders the figure.
struct Series {
  std::string label;  ///< legend text ("" takes the role's name)
  Role role = Role::measured;
  Mark mark = Mark::line;
  std::span<const double> x, y;  ///< SI
};

/// A plot area with its own y axis; the panels of a figure share the x axis and are stacked.
struct Panel {
  std::string name;  ///< data-panel attribute, e.g. "force", "residual"
  Axis y;
  std::vector<Series> series;
  double height = 200;  ///< of the plot area, in SVG units
};

/// A shaded stretch of x (e.g. where the zoom below is taken).
struct Band {
  double lo = 0, hi = 0;
  std::string label;
};

/// A figure: one inline SVG (class "plot", its `id`, data-kind `kind`) and a caption.
struct Figure {
  std::string id;     ///< unique in the document; letters, digits, '-' and '_'
  std::string kind;   ///< what it shows, for the browser check ("time", "loops", ...)
  std::string title;  ///< bold first words of the caption, and the SVG's <title>
  std::string caption;
  double width = 960;  ///< SVG units; 480 for the half-width figures of a grid
  Axis x;
  std::vector<Panel> panels;
  std::optional<Band> band;
};
std::string render_figure(const Figure& figure);

/// Horizontal bars: for each category (row) one bar per group, on a value axis (log or linear),
/// with vertical reference lines (e.g. the noise floor).
struct BarGroup {
  std::string label;
  Role role = Role::validation;
  std::vector<double> values;  ///< one per category; non-finite or <= 0 on a log axis: no bar
};
struct ReferenceLine {
  std::string label;
  double value = 0;
};
struct BarChart {
  std::string id, kind = "bars", title, caption;
  double width = 960;
  Axis value;
  std::vector<std::string> categories;
  std::vector<BarGroup> groups;
  std::vector<ReferenceLine> references;
};
std::string render_bar_chart(const BarChart& chart);

/// A table of text cells (escaped when rendered).
struct Table {
  std::string id, caption;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::vector<bool> numeric;  ///< per column: right-aligned, tabular figures
};
std::string render_table(const Table& table);

/// An HTML document: a title, the summary that opens it, then sections of figures, tables and
/// text.  `html()` gives the complete, self-contained page.
class Document {
 public:
  explicit Document(std::string title);

  /// The one or two sentences that say what the run found (shown first).
  void summary(std::string_view text);
  /// Starts a section (the previous one is closed).
  void section(std::string_view id, std::string_view heading);
  void subheading(std::string_view text);
  void paragraph(std::string_view text);
  /// Figures added between these two are laid out side by side where the page is wide enough.
  void begin_grid();
  void end_grid();
  void add(const Figure& figure);
  void add(const BarChart& chart);
  void add(const Table& table);
  /// A bulleted list of text items (class `cls`).
  void list(std::string_view cls, const std::vector<std::string>& items);
  void preformatted(std::string_view text);
  /// A fragment of HTML the caller has escaped.
  void raw(std::string_view html);

  std::string html() const;

 private:
  std::string title_;
  std::string summary_;
  std::string body_;
  bool in_section_ = false;
  bool in_grid_ = false;
};

/// Writes the document to `path` atomically (atomic_file.hpp).
void write_report(const std::string& path, const Document& document);

}  // namespace friction::report
