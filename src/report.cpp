#include "friction/report.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <unordered_set>
#include <utility>

#include "friction/atomic_file.hpp"
#include "friction/error.hpp"

namespace friction::report {

RoleStyle role_style(Role role) {
  switch (role) {
    case Role::measured:
      return {"measured", "#000000"};
    case Role::simulated:
      return {"simulated", "#0072B2"};
    case Role::residual:
      return {"residual", "#D55E00"};
    case Role::before:
      return {"before", "#E69F00"};
    case Role::after:
      return {"after", "#009E73"};
    case Role::estimation:
      return {"estimation", "#56B4E9"};
    case Role::validation:
      return {"validation", "#CC79A7"};
    case Role::reference:
      return {"reference", "#555555"};
  }
  return {"?", "#000000"};
}

std::string escape_html(std::string_view text) {
  std::string out;
  out.reserve(text.size() + text.size() / 8);
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string format_number(double value, int precision) {
  if (!std::isfinite(value)) return std::isnan(value) ? "n/a" : (value > 0 ? "inf" : "-inf");
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", precision, value);
  return buf;
}

DisplayUnit display_unit(std::string_view si_unit, double magnitude) {
  static const std::string_view prefixable[] = {"m", "N", "s", "m/s", "m/s^2", "N/m", "N s/m"};
  const std::string shown = si_unit == "m/s^2" ? std::string("m/s\u00b2") : std::string(si_unit);
  const bool can_prefix =
      std::find(std::begin(prefixable), std::end(prefixable), si_unit) != std::end(prefixable);
  if (!can_prefix || !(magnitude > 0) || !std::isfinite(magnitude)) return {1.0, shown};
  struct Prefix {
    double scale;
    const char* symbol;
  };
  // Seconds are shown in s above 1 s (no ks); the others take k above 1000.
  static const Prefix prefixes[] = {
      {1e3, "k"}, {1, ""}, {1e-3, "m"}, {1e-6, "\u00b5"}, {1e-9, "n"}};
  for (const auto& p : prefixes) {
    if (p.scale > 1 && si_unit == "s") continue;
    if (magnitude >= p.scale * (1 - 1e-9) || p.scale == 1e-9)
      return {1.0 / p.scale, p.symbol + shown};
  }
  return {1.0, shown};
}

std::vector<double> nice_ticks(double lo, double hi, int target) {
  std::vector<double> ticks;
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo) || target < 1) return ticks;
  // The smallest step of the 1-2-5 series that gives at most target + 1 ticks: as many labels as
  // asked for, and never a single one on a short panel.
  const double power = std::pow(10.0, std::floor(std::log10((hi - lo) / target)) - 1);
  double step = power;
  for (int k = 0; k < 12; ++k) {
    step = std::array<double, 3>{1.0, 2.0, 5.0}[k % 3] * power * std::pow(10.0, k / 3);
    const double n = std::floor(hi / step + 1e-9) - std::ceil(lo / step - 1e-9) + 1;
    if (n <= target + 1) break;
  }
  const double first = std::ceil(lo / step - 1e-9) * step;
  for (double t = first; t <= hi + step * 1e-9; t += step) {
    ticks.push_back(std::abs(t) < step * 1e-9 ? 0.0 : t);
    if (ticks.size() > 100) break;
  }
  return ticks;
}

std::string format_quantity(double value, std::string_view si_unit, int precision) {
  const DisplayUnit du = display_unit(si_unit, std::abs(value));
  return format_number(value * du.factor, precision) + (du.unit.empty() ? "" : " " + du.unit);
}

Runs thin_columns(std::span<const double> px, std::span<const double> py) {
  FRICTION_CHECK(px.size() == py.size(), "thin_columns: ", px.size(), " x against ", py.size(),
                 " y");
  Runs runs;
  std::vector<std::size_t> run;
  bool open = false;  // a column is being accumulated
  double column = 0;
  std::size_t first = 0, last = 0, lowest = 0, highest = 0;
  const auto flush = [&] {
    if (!open) return;
    std::size_t keep[4] = {first, lowest, highest, last};
    std::sort(keep, keep + 4);
    for (std::size_t k = 0; k < 4; ++k)
      if (k == 0 || keep[k] != keep[k - 1]) run.push_back(keep[k]);
    open = false;
  };
  const auto close_run = [&] {
    flush();
    if (!run.empty()) runs.push_back(std::move(run));
    run.clear();
  };
  for (std::size_t i = 0; i < px.size(); ++i) {
    if (!std::isfinite(px[i]) || !std::isfinite(py[i])) {
      close_run();
      continue;
    }
    const double c = std::floor(px[i]);
    if (open && c == column) {
      last = i;
      if (py[i] < py[lowest]) lowest = i;
      if (py[i] > py[highest]) highest = i;
      continue;
    }
    flush();
    open = true;
    column = c;
    first = last = lowest = highest = i;
  }
  close_run();
  return runs;
}

namespace {

// A pixel cell as one 64-bit key (cells far outside any plot never occur: callers clip first).
std::uint64_t cell_key(double px, double py, double cell) {
  const auto cx = static_cast<std::int64_t>(std::floor(px / cell));
  const auto cy = static_cast<std::int64_t>(std::floor(py / cell));
  return (static_cast<std::uint64_t>(cx) << 32) ^ (static_cast<std::uint64_t>(cy) & 0xffffffffu);
}

struct PairHash {
  std::size_t operator()(const std::pair<std::uint64_t, std::uint64_t>& p) const noexcept {
    return std::hash<std::uint64_t>{}(p.first * 0x9e3779b97f4a7c15ull ^ p.second);
  }
};

}  // namespace

Runs thin_points(std::span<const double> px, std::span<const double> py, double cell) {
  FRICTION_CHECK(px.size() == py.size(), "thin_points: ", px.size(), " x against ", py.size(),
                 " y");
  FRICTION_CHECK(cell > 0, "thin_points: the cell must be positive");
  std::unordered_set<std::uint64_t> seen;
  std::vector<std::size_t> kept;
  for (std::size_t i = 0; i < px.size(); ++i) {
    if (!std::isfinite(px[i]) || !std::isfinite(py[i])) continue;
    if (seen.insert(cell_key(px[i], py[i], cell)).second) kept.push_back(i);
  }
  Runs runs;
  if (!kept.empty()) runs.push_back(std::move(kept));
  return runs;
}

Runs thin_polyline(std::span<const double> px, std::span<const double> py, double cell) {
  FRICTION_CHECK(px.size() == py.size(), "thin_polyline: ", px.size(), " x against ", py.size(),
                 " y");
  FRICTION_CHECK(cell > 0, "thin_polyline: the cell must be positive");
  std::unordered_set<std::pair<std::uint64_t, std::uint64_t>, PairHash> drawn;
  Runs runs;
  std::vector<std::size_t> run;
  bool have_previous = false;
  std::uint64_t previous_cell = 0;
  std::size_t previous = 0;
  const auto close_run = [&] {
    if (run.size() >= 2) runs.push_back(std::move(run));
    run.clear();
  };
  for (std::size_t i = 0; i < px.size(); ++i) {
    if (!std::isfinite(px[i]) || !std::isfinite(py[i])) {
      close_run();
      have_previous = false;
      continue;
    }
    const std::uint64_t c = cell_key(px[i], py[i], cell);
    if (!have_previous) {
      have_previous = true;
      previous_cell = c;
      previous = i;
      continue;
    }
    if (c == previous_cell) continue;  // the first sample entering a cell stands for it
    const auto key = std::minmax(previous_cell, c);
    if (drawn.insert({key.first, key.second}).second) {
      if (run.empty() || run.back() != previous) {
        close_run();
        run.push_back(previous);
      }
      run.push_back(i);
    } else {
      close_run();
    }
    previous_cell = c;
    previous = i;
  }
  close_run();
  return runs;
}

namespace {

// ---- SVG writing -------------------------------------------------------------------------------

// A coordinate in SVG units with one decimal (a tenth of a CSS pixel at scale 1), no trailing ".0".
void put(std::string& out, double v) {
  char buf[32];
  const double r = std::round(v * 10.0) / 10.0;
  auto [end, ec] =
      std::to_chars(buf, buf + sizeof buf, r == 0.0 ? 0.0 : r, std::chars_format::fixed, 1);
  if (ec != std::errc()) {
    out += "0";
    return;
  }
  std::string_view s(buf, static_cast<std::size_t>(end - buf));
  if (s.size() > 2 && s.substr(s.size() - 2) == ".0") s.remove_suffix(2);
  out += s;
}

std::string coord(double v) {
  std::string s;
  put(s, v);
  return s;
}

std::string safe_id(std::string_view id) {
  std::string out;
  for (const char c : id)
    out += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_') ? c : '-';
  if (out.empty() || !std::isalpha(static_cast<unsigned char>(out[0]))) out.insert(0, "p-");
  return out;
}

// Tick label in display units: as many decimals as the step needs.
std::string tick_label(double value, double step) {
  const int decimals = std::clamp(static_cast<int>(-std::floor(std::log10(step) + 1e-9)), 0, 9);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
  std::string s = buf;
  if (s == "-0" || (s.rfind("-0.", 0) == 0 && std::strtod(buf, nullptr) == 0.0)) s = s.substr(1);
  // U+2212 MINUS SIGN reads better than a hyphen in figures.
  if (!s.empty() && s[0] == '-') s = "\u2212" + s.substr(1);
  return s;
}

std::string axis_label(const Axis& axis, const DisplayUnit& du) {
  return axis.quantity + " [" + (du.unit.empty() ? std::string("\u2013") : du.unit) + "]";
}

// A linear scale: SI value -> SVG coordinate.
struct Scale {
  double lo = 0, hi = 1;    // SI
  double from = 0, to = 1;  // SVG
  double operator()(double v) const { return from + (v - lo) / (hi - lo) * (to - from); }
};

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool empty() const { return !(hi >= lo); }
};

// Final range of an axis from the data range: fixed ends win; otherwise padded by 4 %, symmetric
// when asked, and never of zero width.
Range settle(const Axis& axis, Range data) {
  if (data.empty()) data = {0.0, 1.0};
  if (axis.symmetric) {
    const double m = std::max(std::abs(data.lo), std::abs(data.hi));
    data = {-m, m};
  }
  double span = data.hi - data.lo;
  if (!(span > 0)) {
    const double m = std::max(std::abs(data.lo), 1e-12);
    data = {data.lo - 0.5 * m, data.hi + 0.5 * m};
    span = data.hi - data.lo;
  }
  Range r{data.lo - 0.04 * span, data.hi + 0.04 * span};
  if (axis.lo) r.lo = *axis.lo;
  if (axis.hi) r.hi = *axis.hi;
  if (!(r.hi > r.lo)) r.hi = r.lo + 1.0;
  return r;
}

// Indices of a series that fall in the x range [lo, hi]: for a non-decreasing x (time series),
// the contiguous block plus one sample on each side, so that a line leaves the plot area at its
// edge (clipped) instead of stopping short of it.
std::pair<std::size_t, std::size_t> visible_block(std::span<const double> x, double lo, double hi) {
  const std::size_t n = x.size();
  if (n == 0) return {0, 0};
  const bool sorted = std::is_sorted(x.begin(), x.end());
  if (!sorted) return {0, n};
  auto b = static_cast<std::size_t>(std::lower_bound(x.begin(), x.end(), lo) - x.begin());
  auto e = static_cast<std::size_t>(std::upper_bound(x.begin(), x.end(), hi) - x.begin());
  if (b > 0) --b;
  if (e < n) ++e;
  return {b, e};
}

constexpr double kMarginLeft = 78, kMarginRight = 18, kMarginTop = 30, kMarginBottom = 46;
constexpr double kPanelGap = 16;
constexpr double kFont = 13;

std::string dash_of(Role role) {
  return role == Role::reference ? " stroke-dasharray=\"6 4\"" : "";
}

// Stroke width of a line in SVG units: the measured force a little wider, so that a simulated line
// drawn over it leaves it visible at both edges.
double line_width(Role role, Mark mark) {
  if (mark == Mark::points) return 2.6;
  return role == Role::measured ? 1.8 : 1.1;
}

void legend(std::string& s, const std::vector<std::pair<std::string, std::pair<Role, Mark>>>& items,
            double right, double y) {
  // Laid out from the right edge leftwards; text width estimated at 0.56 em per character.
  s += "<g class=\"legend\">";
  double x = right;
  for (auto it = items.rbegin(); it != items.rend(); ++it) {
    const auto& [label, style] = *it;
    const double text_w = 0.56 * kFont * static_cast<double>(label.size());
    x -= text_w;
    s +=
        "<text x=\"" + coord(x) + "\" y=\"" + coord(y + 4) + "\">" + escape_html(label) + "</text>";
    const std::string colour(role_style(style.first).colour);
    x -= 6;
    if (style.second == Mark::points) {
      s += "<circle cx=\"" + coord(x - 8) + "\" cy=\"" + coord(y) + "\" r=\"3\" fill=\"" + colour +
           "\"/>";
    } else {
      s += "<line x1=\"" + coord(x - 18) + "\" y1=\"" + coord(y) + "\" x2=\"" + coord(x) +
           "\" y2=\"" + coord(y) + "\" stroke=\"" + colour + "\" stroke-width=\"2.5\"" +
           dash_of(style.first) + "/>";
    }
    x -= 18 + 16;
  }
  s += "</g>";
}

// The path of a series' kept runs: "M x y L x y ..." for lines, "M x yh0" dots for points (a
// zero-length subpath with round caps is a dot: one short command per mark).
void series_path(std::string& s, const Series& series, const Runs& runs, const Scale& sx,
                 const Scale& sy) {
  const std::string colour(role_style(series.role).colour);
  const std::string name =
      series.label.empty() ? std::string(role_style(series.role).name) : series.label;
  std::size_t marks = 0;
  for (const auto& r : runs) marks += r.size();
  s += "<path class=\"series\" data-series=\"" + escape_html(name) + "\" data-role=\"" +
       std::string(role_style(series.role).name) + "\" data-marks=\"" + std::to_string(marks) +
       "\" fill=\"none\" stroke=\"" + colour + "\" stroke-width=\"" +
       coord(line_width(series.role, series.mark)) + "\"";
  if (series.mark == Mark::points)
    s += " stroke-linecap=\"round\"";
  else
    s += " stroke-linejoin=\"round\" stroke-linecap=\"round\"";
  s += dash_of(series.role);
  s += " d=\"";
  for (const auto& run : runs) {
    if (series.mark == Mark::points) {
      for (const std::size_t i : run) {
        s += 'M';
        put(s, sx(series.x[i]));
        s += ' ';
        put(s, sy(series.y[i]));
        s += "h0";
      }
      continue;
    }
    bool first = true;
    for (const std::size_t i : run) {
      s += first ? 'M' : 'L';
      first = false;
      put(s, sx(series.x[i]));
      s += ' ';
      put(s, sy(series.y[i]));
    }
  }
  s += "\"/>";
}

// Indices of series drawn within [x range] x [y range] (points and loops outside are dropped; the
// thinning works on pixel coordinates).
Runs thin_series(const Series& series, const Scale& sx, const Scale& sy, std::size_t b,
                 std::size_t e) {
  const std::size_t n = e - b;
  std::vector<double> px(n), py(n);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double x0 = std::min(sx.from, sx.to), x1 = std::max(sx.from, sx.to);
  const double y0 = std::min(sy.from, sy.to), y1 = std::max(sy.from, sy.to);
  for (std::size_t k = 0; k < n; ++k) {
    const double x = series.x[b + k], y = series.y[b + k];
    px[k] = std::isfinite(x) ? sx(x) : nan;
    py[k] = std::isfinite(y) ? sy(y) : nan;
    if (series.mark != Mark::line &&
        (px[k] < x0 - 0.5 || px[k] > x1 + 0.5 || py[k] < y0 - 0.5 || py[k] > y1 + 0.5))
      px[k] = nan;
  }
  Runs runs;
  switch (series.mark) {
    case Mark::line:
      runs = thin_columns(px, py);
      break;
    case Mark::points:
      runs = thin_points(px, py, 2.0);
      break;
    case Mark::polyline:
      runs = thin_polyline(px, py, 2.0);
      break;
  }
  for (auto& r : runs)
    for (auto& i : r) i += b;
  return runs;
}

std::string svg_open(const std::string& id, const std::string& kind, const std::string& title,
                     double width, double height) {
  return "<svg class=\"plot\" id=\"" + id + "\" data-kind=\"" + escape_html(kind) +
         "\" viewBox=\"0 0 " + coord(width) + " " + coord(height) + "\" font-size=\"" +
         coord(kFont) + "\" role=\"img\"><title>" + escape_html(title) + "</title>";
}

std::string caption_html(const std::string& title, const std::string& caption) {
  std::string s = "<figcaption>";
  if (!title.empty()) s += "<b>" + escape_html(title) + ".</b> ";
  s += escape_html(caption) + "</figcaption>";
  return s;
}

}  // namespace

std::string render_figure(const Figure& f) {
  FRICTION_CHECK(!f.panels.empty(), "render_figure: figure '", f.id, "' has no panel");
  const std::string id = safe_id(f.id);
  const double left = kMarginLeft, right = f.width - kMarginRight;
  double height = kMarginTop + kMarginBottom;
  for (const auto& p : f.panels) height += p.height;
  height += kPanelGap * static_cast<double>(f.panels.size() - 1);

  // The x range: fixed, or over every finite x of every series.
  Range xdata;
  if (!(f.x.lo && f.x.hi))
    for (const auto& p : f.panels)
      for (const auto& s : p.series)
        for (const double v : s.x) xdata.add(v);
  Range xr = settle(f.x, xdata);
  if (!(f.x.lo && f.x.hi) && !f.panels.empty()) {
    // Time series fill the width: no padding when every series is a line.
    bool all_lines = true;
    for (const auto& p : f.panels)
      for (const auto& s : p.series) all_lines = all_lines && s.mark == Mark::line;
    if (all_lines && !xdata.empty() && xdata.hi > xdata.lo) xr = {xdata.lo, xdata.hi};
  }
  const DisplayUnit xu = display_unit(f.x.unit, std::max(std::abs(xr.lo), std::abs(xr.hi)));
  const Scale sx{xr.lo, xr.hi, left, right};

  std::string s = "<figure class=\"plot-figure\">";
  s += svg_open(id, f.kind, f.title, f.width, height);
  s += "<defs>";
  double top = kMarginTop;
  for (std::size_t k = 0; k < f.panels.size(); ++k) {
    s += "<clipPath id=\"" + id + "-clip" + std::to_string(k) + "\"><rect x=\"" + coord(left) +
         "\" y=\"" + coord(top) + "\" width=\"" + coord(right - left) + "\" height=\"" +
         coord(f.panels[k].height) + "\"/></clipPath>";
    top += f.panels[k].height + kPanelGap;
  }
  s += "</defs>";

  // The legend: every distinct (label, role) of the figure, once.
  std::vector<std::pair<std::string, std::pair<Role, Mark>>> items;
  for (const auto& p : f.panels)
    for (const auto& ser : p.series) {
      const std::string name =
          ser.label.empty() ? std::string(role_style(ser.role).name) : ser.label;
      // One entry per colour: a residual drawn in its model's colour (two models in one view)
      // needs no entry of its own.
      const bool known = std::any_of(items.begin(), items.end(), [&](const auto& it) {
        return it.first == name || it.second.first == ser.role;
      });
      if (!known) items.push_back({name, {ser.role, ser.mark}});
    }
  legend(s, items, right, kMarginTop / 2);

  const std::vector<double> xticks = nice_ticks(xr.lo, xr.hi, static_cast<int>(f.width / 110));
  const double xstep = xticks.size() > 1 ? xticks[1] - xticks[0] : (xr.hi - xr.lo);

  top = kMarginTop;
  for (std::size_t k = 0; k < f.panels.size(); ++k) {
    const Panel& p = f.panels[k];
    const double bottom = top + p.height;
    // Visible blocks, then the y range over what is visible.
    std::vector<std::pair<std::size_t, std::size_t>> blocks;
    Range ydata;
    for (const auto& ser : p.series) {
      FRICTION_CHECK(ser.x.size() == ser.y.size(), "render_figure: series '", ser.label, "' of '",
                     f.id, "' has ", ser.x.size(), " x and ", ser.y.size(), " y");
      const auto blk = visible_block(ser.x, xr.lo, xr.hi);
      blocks.push_back(blk);
      for (std::size_t i = blk.first; i < blk.second; ++i)
        if (ser.x[i] >= xr.lo && ser.x[i] <= xr.hi) ydata.add(ser.y[i]);
    }
    const Range yr = settle(p.y, ydata);
    const Scale sy{yr.lo, yr.hi, bottom, top};
    const DisplayUnit yu = display_unit(p.y.unit, std::max(std::abs(yr.lo), std::abs(yr.hi)));

    s += "<g class=\"panel\" data-panel=\"" + escape_html(p.name) + "\">";
    s += "<rect class=\"plot-area\" x=\"" + coord(left) + "\" y=\"" + coord(top) + "\" width=\"" +
         coord(right - left) + "\" height=\"" + coord(p.height) +
         "\" fill=\"#ffffff\" stroke=\"#b0b0b0\"/>";
    if (f.band && f.band->hi > xr.lo && f.band->lo < xr.hi) {
      const double b0 = sx(std::max(f.band->lo, xr.lo)), b1 = sx(std::min(f.band->hi, xr.hi));
      s += "<rect class=\"band\" x=\"" + coord(b0) + "\" y=\"" + coord(top) + "\" width=\"" +
           coord(std::max(b1 - b0, 1.0)) + "\" height=\"" + coord(p.height) +
           "\" fill=\"#000000\" fill-opacity=\"0.07\"/>";
      if (k == 0 && !f.band->label.empty())
        s += "<text x=\"" + coord(b0 + 3) + "\" y=\"" + coord(top + kFont + 2) +
             "\" font-size=\"11\" fill=\"#444\" stroke=\"#ffffff\" stroke-width=\"3\" "
             "paint-order=\"stroke\">" +
             escape_html(f.band->label) + "</text>";
    }
    // Grid and ticks.
    const std::vector<double> yticks =
        nice_ticks(yr.lo, yr.hi, std::max(3, static_cast<int>(p.height / 40)));
    const double ystep = yticks.size() > 1 ? yticks[1] - yticks[0] : (yr.hi - yr.lo);
    s += "<g class=\"grid\" stroke=\"#e4e4e4\">";
    for (const double t : yticks)
      s += "<line x1=\"" + coord(left) + "\" x2=\"" + coord(right) + "\" y1=\"" + coord(sy(t)) +
           "\" y2=\"" + coord(sy(t)) + "\"/>";
    for (const double t : xticks)
      s += "<line y1=\"" + coord(top) + "\" y2=\"" + coord(bottom) + "\" x1=\"" + coord(sx(t)) +
           "\" x2=\"" + coord(sx(t)) + "\"/>";
    s += "</g>";
    if (p.y.symmetric || (yr.lo < 0 && yr.hi > 0))
      s += "<line class=\"zero\" x1=\"" + coord(left) + "\" x2=\"" + coord(right) + "\" y1=\"" +
           coord(sy(0)) + "\" y2=\"" + coord(sy(0)) + "\" stroke=\"#c8c8c8\"/>";
    s += "<g class=\"axis y\" text-anchor=\"end\">";
    for (const double t : yticks)
      s += "<text x=\"" + coord(left - 6) + "\" y=\"" + coord(sy(t) + 4) + "\">" +
           tick_label(t * yu.factor, ystep * yu.factor) + "</text>";
    s += "</g>";
    s += "<text class=\"axis-label y\" text-anchor=\"middle\" transform=\"translate(" + coord(16) +
         "," + coord((top + bottom) / 2) + ") rotate(-90)\">" + escape_html(axis_label(p.y, yu)) +
         "</text>";
    // Marks.
    s += "<g class=\"marks\" clip-path=\"url(#" + id + "-clip" + std::to_string(k) + ")\">";
    for (std::size_t j = 0; j < p.series.size(); ++j) {
      const auto runs = thin_series(p.series[j], sx, sy, blocks[j].first, blocks[j].second);
      series_path(s, p.series[j], runs, sx, sy);
    }
    s += "</g></g>";
    top = bottom + kPanelGap;
  }
  // The x axis under the last panel.
  const double bottom = top - kPanelGap;
  s += "<g class=\"axis x\" text-anchor=\"middle\">";
  for (const double t : xticks)
    s += "<text x=\"" + coord(sx(t)) + "\" y=\"" + coord(bottom + 17) + "\">" +
         tick_label(t * xu.factor, xstep * xu.factor) + "</text>";
  s += "</g>";
  s += "<text class=\"axis-label x\" text-anchor=\"middle\" x=\"" + coord((left + right) / 2) +
       "\" y=\"" + coord(height - 8) + "\">" + escape_html(axis_label(f.x, xu)) + "</text>";
  s += "</svg>" + caption_html(f.title, f.caption) + "</figure>\n";
  return s;
}

std::string render_bar_chart(const BarChart& c) {
  FRICTION_CHECK(!c.categories.empty() && !c.groups.empty(), "render_bar_chart: chart '", c.id,
                 "' has nothing to draw");
  const std::string id = safe_id(c.id);
  const double bar_h = 16, bar_gap = 3, category_gap = 14;
  const double left = 90, right = c.width - kMarginRight - 10;
  const double per_category =
      static_cast<double>(c.groups.size()) * (bar_h + bar_gap) - bar_gap + category_gap;
  const double plot_h = per_category * static_cast<double>(c.categories.size()) + category_gap;
  const double top = kMarginTop + 6, bottom = top + plot_h;
  const double height = bottom + kMarginBottom;

  Range data;
  for (const auto& g : c.groups)
    for (const double v : g.values)
      if (!c.value.log || v > 0) data.add(v);
  for (const auto& r : c.references)
    if (!c.value.log || r.value > 0) data.add(r.value);
  if (data.empty()) data = {1, 10};

  std::string s = "<figure class=\"plot-figure\">" + svg_open(id, c.kind, c.title, c.width, height);
  std::vector<std::pair<std::string, std::pair<Role, Mark>>> items;
  for (const auto& g : c.groups)
    items.push_back(
        {g.label.empty() ? std::string(role_style(g.role).name) : g.label, {g.role, Mark::line}});
  for (const auto& r : c.references) items.push_back({r.label, {Role::reference, Mark::line}});
  legend(s, items, right, kMarginTop / 2);

  // Value scale (log: whole decades around the data).
  double lo, hi;
  std::vector<double> ticks;
  std::vector<std::string> labels;
  DisplayUnit du{1.0, c.value.unit};
  if (c.value.log) {
    lo = std::pow(10.0, std::floor(std::log10(data.lo)));
    hi = std::pow(10.0, std::ceil(std::log10(data.hi)));
    if (!(hi > lo)) hi = lo * 10;
    for (double t = lo; t <= hi * 1.0001; t *= 10) {
      ticks.push_back(t);
      labels.push_back(format_number(t, 3));
    }
  } else {
    const Range r = settle(c.value, {std::min(0.0, data.lo), data.hi});
    lo = std::min(0.0, r.lo);
    hi = r.hi;
    du = display_unit(c.value.unit, std::max(std::abs(lo), std::abs(hi)));
    ticks = nice_ticks(lo, hi, 6);
    const double step = ticks.size() > 1 ? ticks[1] - ticks[0] : hi - lo;
    for (const double t : ticks) labels.push_back(tick_label(t * du.factor, step * du.factor));
  }
  const auto sx = [&](double v) {
    if (c.value.log)
      return left +
             (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo)) * (right - left);
    return left + (v - lo) / (hi - lo) * (right - left);
  };

  s += "<g class=\"panel\" data-panel=\"bars\">";
  s += "<rect class=\"plot-area\" x=\"" + coord(left) + "\" y=\"" + coord(top) + "\" width=\"" +
       coord(right - left) + "\" height=\"" + coord(plot_h) +
       "\" fill=\"#ffffff\" stroke=\"#b0b0b0\"/>";
  s += "<g class=\"grid\" stroke=\"#e4e4e4\">";
  for (const double t : ticks)
    s += "<line y1=\"" + coord(top) + "\" y2=\"" + coord(bottom) + "\" x1=\"" + coord(sx(t)) +
         "\" x2=\"" + coord(sx(t)) + "\"/>";
  s += "</g><g class=\"axis x\" text-anchor=\"middle\">";
  for (std::size_t k = 0; k < ticks.size(); ++k)
    s += "<text x=\"" + coord(sx(ticks[k])) + "\" y=\"" + coord(bottom + 17) + "\">" + labels[k] +
         "</text>";
  s += "</g><g class=\"axis y\" text-anchor=\"end\">";
  for (std::size_t k = 0; k < c.categories.size(); ++k) {
    const double y0 = top + category_gap + per_category * static_cast<double>(k);
    const double mid = y0 + (per_category - category_gap) / 2;
    s += "<text x=\"" + coord(left - 8) + "\" y=\"" + coord(mid + 4) + "\">" +
         escape_html(c.categories[k]) + "</text>";
  }
  s += "</g>";
  s += "<g class=\"marks\">";
  const double base = c.value.log ? lo : 0.0;
  for (std::size_t k = 0; k < c.categories.size(); ++k) {
    const double y0 = top + category_gap + per_category * static_cast<double>(k);
    for (std::size_t g = 0; g < c.groups.size(); ++g) {
      const auto& grp = c.groups[g];
      if (k >= grp.values.size()) continue;
      const double v = grp.values[k];
      if (!std::isfinite(v) || (c.value.log && !(v > 0))) continue;
      const double x0 = sx(std::min(base, v)), x1 = sx(std::max(base, v));
      const double y = y0 + static_cast<double>(g) * (bar_h + bar_gap);
      s += "<rect class=\"bar\" data-series=\"" +
           escape_html(grp.label.empty() ? std::string(role_style(grp.role).name) : grp.label) +
           "\" data-category=\"" + escape_html(c.categories[k]) + "\" data-value=\"" +
           format_number(v, 6) + "\" x=\"" + coord(x0) + "\" y=\"" + coord(y) + "\" width=\"" +
           coord(std::max(x1 - x0, 1.0)) + "\" height=\"" + coord(bar_h) + "\" fill=\"" +
           std::string(role_style(grp.role).colour) + "\"/>";
      s += "<text x=\"" + coord(x1 + 4) + "\" y=\"" + coord(y + bar_h - 4) +
           "\" font-size=\"11\">" + escape_html(format_number(v, 4)) + "</text>";
    }
  }
  for (const auto& r : c.references) {
    if (c.value.log && !(r.value > 0)) continue;
    const double x = sx(r.value);
    s += "<path class=\"reference\" data-series=\"" + escape_html(r.label) + "\" d=\"M" + coord(x) +
         " " + coord(top) + "V" + coord(bottom) + "\" stroke=\"" +
         std::string(role_style(Role::reference).colour) +
         "\" stroke-width=\"2\" stroke-dasharray=\"6 4\"/>";
  }
  s += "</g></g>";
  s += "<text class=\"axis-label x\" text-anchor=\"middle\" x=\"" + coord((left + right) / 2) +
       "\" y=\"" + coord(height - 8) + "\">" +
       escape_html(axis_label(c.value, du) + (c.value.log ? ", log scale" : "")) + "</text>";
  s += "</svg>" + caption_html(c.title, c.caption) + "</figure>\n";
  return s;
}

std::string render_table(const Table& t) {
  std::string s = "<table";
  if (!t.id.empty()) s += " id=\"" + safe_id(t.id) + "\"";
  s += ">";
  if (!t.caption.empty()) s += "<caption>" + escape_html(t.caption) + "</caption>";
  const auto numeric = [&](std::size_t c) { return c < t.numeric.size() && t.numeric[c]; };
  if (!t.header.empty()) {
    s += "<thead><tr>";
    for (std::size_t c = 0; c < t.header.size(); ++c)
      s += std::string(numeric(c) ? "<th class=\"num\">" : "<th>") + escape_html(t.header[c]) +
           "</th>";
    s += "</tr></thead>";
  }
  s += "<tbody>";
  for (const auto& row : t.rows) {
    s += "<tr>";
    for (std::size_t c = 0; c < row.size(); ++c)
      s += std::string(numeric(c) ? "<td class=\"num\">" : "<td>") + escape_html(row[c]) + "</td>";
    s += "</tr>";
  }
  s += "</tbody></table>\n";
  return s;
}

namespace {

// The stylesheet: readable on a laptop (a measure of ~1200 px, figures scaled to the width), and
// in print (A4/Letter: smaller type, figures kept whole, grids of two, colours printed as they
// are).
constexpr const char* kStyle = R"css(
:root{color-scheme:light}
*{box-sizing:border-box}
body{margin:0;background:#fff;color:#1b1b1b;font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",Arial,sans-serif;-webkit-print-color-adjust:exact;print-color-adjust:exact}
main{max-width:1200px;margin:0 auto;padding:1.4rem 1.4rem 3rem}
h1{font-size:1.45rem;margin:0 0 .6rem}
h2{font-size:1.2rem;margin:2.2rem 0 .7rem;padding-bottom:.25rem;border-bottom:1px solid #d8d8d8}
h3{font-size:1.02rem;margin:1.4rem 0 .4rem}
p{margin:.5rem 0;max-width:75em}
.summary{font-size:1.08rem;background:#f3f6f9;border-left:4px solid #0072B2;padding:.75rem 1rem;margin:.4rem 0 1rem}
figure{margin:.8rem 0 1.2rem;break-inside:avoid;page-break-inside:avoid}
svg.plot{display:block;width:100%;height:auto;font-family:inherit}
svg.plot text{fill:#222}
figcaption{font-size:.88rem;color:#3c3c3c;margin-top:.2rem;max-width:75em}
.grid{display:grid;grid-template-columns:repeat(auto-fit,minmax(430px,1fr));gap:0 1.4rem}
table{border-collapse:collapse;font-size:.9rem;margin:.5rem 0 1rem;break-inside:avoid}
caption{text-align:left;font-weight:600;padding:.2rem 0 .35rem}
th,td{border-bottom:1px solid #e2e2e2;padding:.28rem .65rem;text-align:left;vertical-align:top}
th{background:#f5f5f5}
.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
pre{white-space:pre-wrap;word-break:break-word;background:#f5f5f5;padding:.6rem .8rem;font-size:.85rem}
ul.warnings li{margin:.3rem 0}
footer{margin-top:2.5rem;color:#555;font-size:.85rem}
@media (max-width:700px){body{font-size:14px}main{padding:.8rem}.grid{grid-template-columns:1fr}}
@media print{body{font-size:9.5pt}main{max-width:none;padding:0}.grid{grid-template-columns:1fr 1fr}h2{break-after:avoid;page-break-after:avoid}.summary{border:1px solid #888}}
@page{margin:14mm}
)css";

}  // namespace

Document::Document(std::string title) : title_(std::move(title)) {}

void Document::summary(std::string_view text) {
  summary_ = escape_html(text);
}

void Document::section(std::string_view id, std::string_view heading) {
  if (in_grid_) end_grid();
  if (in_section_) body_ += "</section>\n";
  body_ += "<section id=\"" + safe_id(id) + "\"><h2>" + escape_html(heading) + "</h2>\n";
  in_section_ = true;
}

void Document::subheading(std::string_view text) {
  if (in_grid_) end_grid();
  body_ += "<h3>" + escape_html(text) + "</h3>\n";
}

void Document::paragraph(std::string_view text) {
  body_ += "<p>" + escape_html(text) + "</p>\n";
}

void Document::begin_grid() {
  if (in_grid_) return;
  body_ += "<div class=\"grid\">\n";
  in_grid_ = true;
}

void Document::end_grid() {
  if (!in_grid_) return;
  body_ += "</div>\n";
  in_grid_ = false;
}

void Document::add(const Figure& figure) {
  body_ += render_figure(figure);
}
void Document::add(const BarChart& chart) {
  body_ += render_bar_chart(chart);
}
void Document::add(const Table& table) {
  body_ += render_table(table);
}

void Document::list(std::string_view cls, const std::vector<std::string>& items) {
  body_ += "<ul class=\"" + escape_html(cls) + "\">";
  for (const auto& item : items) body_ += "<li>" + escape_html(item) + "</li>";
  body_ += "</ul>\n";
}

void Document::preformatted(std::string_view text) {
  body_ += "<pre>" + escape_html(text) + "</pre>\n";
}

void Document::raw(std::string_view html) {
  body_ += html;
}

std::string Document::html() const {
  std::string s;
  s.reserve(body_.size() + 4096);
  s += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  // Nothing may be fetched: styles are inline, figures are inline SVG, there are no scripts.
  s += "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; "
       "style-src 'unsafe-inline'; img-src data:\">\n";
  s += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
  s += "<title>" + escape_html(title_) + "</title>\n<style>" + kStyle + "</style>\n</head>\n";
  s += "<body>\n<main>\n<h1>" + escape_html(title_) + "</h1>\n";
  if (!summary_.empty()) s += "<p class=\"summary\" id=\"summary\">" + summary_ + "</p>\n";
  s += body_;
  if (in_grid_) s += "</div>\n";
  if (in_section_) s += "</section>\n";
  s += "</main>\n</body>\n</html>\n";
  return s;
}

void write_report(const std::string& path, const Document& document) {
  write_file_atomically(path, document.html());
}

}  // namespace friction::report
