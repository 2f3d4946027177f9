// CSV records: reading with precise errors, writing with round-trip numbers (see csv.hpp).
#include "friction/csv.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <ostream>
#include <sstream>
#include <system_error>

#include "friction/atomic_file.hpp"

namespace friction {
namespace {

// ---------------------------------------------------------------- small string helpers

bool is_blank(char c) {
  return c == ' ' || c == '\t';
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string r(s);
  for (char& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

bool iequals(std::string_view a, std::string_view b) {
  return lower(a) == lower(b);
}

// A cell shown in a message: quoted, cut to a readable length.
std::string shown(std::string_view cell) {
  constexpr std::size_t kMax = 40;
  std::string s = "'";
  s += cell.size() > kMax ? std::string(cell.substr(0, kMax)) + "..." : std::string(cell);
  return s + "'";
}

// "a, b or c"
std::string list(std::span<const std::string_view> names, const char* last = " or ") {
  std::string s;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) s += (i + 1 == names.size()) ? last : ", ";
    s += names[i];
  }
  return s;
}

// ---------------------------------------------------------------- roles and their header names

enum Role { kTime, kDisplacement, kForce, kNormal, kRoles };

constexpr std::array<const char*, kRoles> kRoleName = {"time", "displacement", "force", "normal"};

const std::array<std::vector<std::string_view>, kRoles>& aliases() {
  static const std::array<std::vector<std::string_view>, kRoles> a = {{
      {"time", "t", "time_s"},
      {"displacement", "position", "x", "position_m"},
      {"force", "friction", "f", "friction_force_n"},
      {"normal", "normal_force", "normal_force_n"},
  }};
  return a;
}

std::optional<Role> role_of_key(std::string_view key) {
  const std::string k = lower(trim(key));
  for (int r = 0; r < kRoles; ++r)
    if (k == kRoleName[r]) return static_cast<Role>(r);
  return std::nullopt;
}

// Splits "key=value,key=value" into pairs; throws OptionError naming `option` on malformed items.
std::vector<std::pair<std::string_view, std::string_view>> key_values(std::string_view spec,
                                                                      const char* option) {
  std::vector<std::pair<std::string_view, std::string_view>> items;
  if (trim(spec).empty()) throw OptionError(std::string(option) + ": empty value");
  while (true) {
    const std::size_t comma = spec.find(',');
    const std::string_view item = trim(spec.substr(0, comma));
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos || trim(item.substr(0, eq)).empty() ||
        trim(item.substr(eq + 1)).empty())
      throw OptionError(std::string(option) + ": expected KEY=VALUE, got " + shown(item));
    items.emplace_back(trim(item.substr(0, eq)), trim(item.substr(eq + 1)));
    if (comma == std::string_view::npos) break;
    spec.remove_prefix(comma + 1);
  }
  return items;
}

// ---------------------------------------------------------------- units

struct UnitEntry {
  std::string_view symbol;
  double factor;
};

constexpr std::array<UnitEntry, 9> kTimeUnits = {{{"s", 1.0},
                                                  {"ms", 1e-3},
                                                  {"us", 1e-6},
                                                  {"\xC2\xB5s", 1e-6},
                                                  {"\xCE\xBCs", 1e-6},
                                                  {"ns", 1e-9},
                                                  {"min", 60.0},
                                                  {"h", 3600.0},
                                                  {"", 0.0}}};
constexpr std::array<UnitEntry, 9> kLengthUnits = {{{"m", 1.0},
                                                    {"cm", 1e-2},
                                                    {"mm", 1e-3},
                                                    {"um", 1e-6},
                                                    {"\xC2\xB5m", 1e-6},
                                                    {"\xCE\xBCm", 1e-6},
                                                    {"nm", 1e-9},
                                                    {"", 0.0},
                                                    {"", 0.0}}};
constexpr std::array<UnitEntry, 9> kForceUnits = {{{"N", 1.0},
                                                   {"kN", 1e3},
                                                   {"mN", 1e-3},
                                                   {"uN", 1e-6},
                                                   {"\xC2\xB5N", 1e-6},
                                                   {"\xCE\xBCN", 1e-6},
                                                   {"nN", 1e-9},
                                                   {"", 0.0},
                                                   {"", 0.0}}};

// ---------------------------------------------------------------- numbers

// Strict parse of one whole cell; nullopt plus a reason when it is not a finite double.
std::optional<double> parse_number(std::string_view cell, std::string& why) {
  if (cell.empty()) {
    why = "empty cell, expected a number";
    return std::nullopt;
  }
  std::string_view s = cell;
  if (s.size() > 1 && s.front() == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec == std::errc::result_out_of_range && ptr == s.data() + s.size()) {
    // Underflow (1e-400) reads as 0 or a subnormal, harmlessly; overflow (1e999) is refused.
    const std::string copy(s);
    const double approx = std::strtod(copy.c_str(), nullptr);
    if (std::isinf(approx)) {
      why = shown(cell) + " is beyond the range of a double, expected a finite number";
      return std::nullopt;
    }
    return approx;
  }
  if (ec != std::errc() || ptr != s.data() + s.size()) {
    why = "expected a number, got " + shown(cell);
    return std::nullopt;
  }
  if (!std::isfinite(v)) {
    why = shown(cell) + " is not finite (NaN and Inf are not allowed), expected a finite number";
    return std::nullopt;
  }
  return v;
}

// ---------------------------------------------------------------- the reader

class Reader {
 public:
  Reader(std::string_view text, std::string name, const ReadOptions& options)
      : text_(text), name_(std::move(name)), options_(options) {}

  Record read();

 private:
  [[noreturn]] void fail(long line, long column, const std::string& what) const {
    throw DataError(name_, line, column, what);
  }

  void check_encoding() const;
  // Splits one line into cells (unquoted, trimmed); fails on an unterminated quote.
  void split(std::string_view line, long line_no, std::vector<std::string>& cells) const;
  void resolve_columns(const std::vector<std::string>& header, long header_line);
  std::string column_label(int column) const;  // "column 3 ('force')"

  std::string_view text_;
  std::string name_;
  const ReadOptions& options_;
  char delimiter_ = ',';
  std::vector<std::string> header_;
  std::array<int, kRoles> column_{-1, -1, -1, -1};  // 0-based CSV column of each role
};

// Rejects binary data before anything else, so that its message is about the bytes, not about
// a "non-numeric cell".  Valid UTF-8 (no overlongs, surrogates or code points past U+10FFFF);
// control characters other than tab, CR and LF are refused (NUL first of all).
void Reader::check_encoding() const {
  long line = 1, column = 1;
  const auto* p = reinterpret_cast<const unsigned char*>(text_.data());
  const std::size_t n = text_.size();
  std::size_t line_start = 0;
  const auto field_of = [&](std::size_t pos) {
    long field = 1;
    for (std::size_t i = line_start; i < pos; ++i)
      if (text_[i] == delimiter_) ++field;
    return field;
  };
  const auto bad = [&](std::size_t pos, const std::string& what) {
    std::ostringstream s;
    s << what << " at character " << column << " of the line: this looks like binary data, "
      << "expected UTF-8 CSV text";
    fail(line, field_of(pos), s.str());
  };
  for (std::size_t i = 0; i < n;) {
    const unsigned char c = p[i];
    if (c == '\n' || c == '\r') {
      if (c == '\r' && i + 1 < n && p[i + 1] == '\n') ++i;
      ++i;
      ++line;
      column = 1;
      line_start = i;
      continue;
    }
    if (c < 0x80) {
      if (c == 0) bad(i, "NUL byte");
      if ((c < 0x20 && c != '\t') || c == 0x7F) {
        char hex[8];
        std::snprintf(hex, sizeof hex, "0x%02X", c);
        bad(i, std::string("control character ") + hex);
      }
      ++i;
      ++column;
      continue;
    }
    std::size_t len = 0;
    std::uint32_t cp = 0;
    if (c >= 0xC2 && c <= 0xDF) {
      len = 2;
      cp = c & 0x1F;
    } else if (c >= 0xE0 && c <= 0xEF) {
      len = 3;
      cp = c & 0x0F;
    } else if (c >= 0xF0 && c <= 0xF4) {
      len = 4;
      cp = c & 0x07;
    } else {
      bad(i, "invalid UTF-8 byte");
    }
    if (i + len > n) bad(i, "truncated UTF-8 sequence");
    for (std::size_t k = 1; k < len; ++k) {
      if ((p[i + k] & 0xC0) != 0x80) bad(i, "invalid UTF-8 sequence");
      cp = (cp << 6) | (p[i + k] & 0x3F);
    }
    if ((len == 3 && (cp < 0x800 || (cp >= 0xD800 && cp <= 0xDFFF))) ||
        (len == 4 && (cp < 0x10000 || cp > 0x10FFFF)))
      bad(i, "invalid UTF-8 sequence");
    if (cp >= 0x80 && cp <= 0x9F) bad(i, "control character");
    i += len;
    ++column;
  }
}

void Reader::split(std::string_view line, long line_no, std::vector<std::string>& cells) const {
  cells.clear();
  std::size_t i = 0;
  while (true) {
    std::string cell;
    while (i < line.size() && is_blank(line[i])) ++i;
    if (i < line.size() && line[i] == '"') {
      ++i;
      bool closed = false;
      while (i < line.size()) {
        if (line[i] == '"') {
          if (i + 1 < line.size() && line[i + 1] == '"') {
            cell += '"';
            i += 2;
            continue;
          }
          ++i;
          closed = true;
          break;
        }
        cell += line[i++];
      }
      if (!closed)
        fail(line_no, static_cast<long>(cells.size() + 1),
             "unterminated quoted cell, expected a closing '\"' on the same line");
      while (i < line.size() && is_blank(line[i])) ++i;
      if (i < line.size() && line[i] != delimiter_)
        fail(line_no, static_cast<long>(cells.size() + 1),
             "text after a closing quote, expected a separator");
      cells.push_back(std::string(trim(cell)));
    } else {
      const std::size_t end = std::min(line.find(delimiter_, i), line.size());
      cells.push_back(std::string(trim(line.substr(i, end - i))));
      i = end;
    }
    if (i >= line.size()) break;
    ++i;  // the separator
  }
}

std::string Reader::column_label(int column) const {
  return "column " + std::to_string(column + 1) + " (" + shown(header_[column]) + ")";
}

void Reader::resolve_columns(const std::vector<std::string>& header, long header_line) {
  const std::array<const std::string*, kRoles> given = {
      &options_.columns.time, &options_.columns.displacement, &options_.columns.force,
      &options_.columns.normal};
  std::vector<std::string_view> names(header.begin(), header.end());
  const std::string found = "the header has " + list(names, " and ");
  for (int r = 0; r < kRoles; ++r) {
    std::vector<int> matches;
    const std::string want = std::string(trim(*given[r]));
    for (int c = 0; c < static_cast<int>(header.size()); ++c) {
      if (!want.empty()) {
        if (iequals(header[c], want)) matches.push_back(c);
      } else {
        for (std::string_view a : aliases()[r])
          if (iequals(header[c], a)) matches.push_back(c);
      }
    }
    const bool required =
        r == kTime || r == kDisplacement || (r == kForce && options_.require_force);
    if (matches.empty()) {
      if (!want.empty())
        fail(header_line, 0,
             "no column named " + shown(want) + " (given for " + kRoleName[r] + " by --columns), " +
                 found);
      if (required)
        fail(header_line, 0,
             std::string("no ") + kRoleName[r] + " column: expected a header named " +
                 list(aliases()[r]) + " (any case) or --columns " + kRoleName[r] + "=NAME; " +
                 found);
      continue;
    }
    if (matches.size() > 1)
      fail(header_line, matches[1] + 1,
           column_label(matches[0]) + " and " + column_label(matches[1]) + " both name the " +
               kRoleName[r] + " signal, expected one; choose with --columns " + kRoleName[r] +
               "=NAME");
    for (int o = 0; o < r; ++o)
      if (column_[o] == matches[0])
        fail(header_line, matches[0] + 1,
             column_label(matches[0]) + " is used for both " + kRoleName[o] + " and " +
                 kRoleName[r] + ", expected a column of its own for each");
    column_[r] = matches[0];
  }
}

Record Reader::read() {
  // Lines are split on LF, CRLF or CR.  `lines` holds views into the text.
  if (text_.size() >= 3 && text_.substr(0, 3) == "\xEF\xBB\xBF") text_.remove_prefix(3);
  {
    const std::size_t start = std::min(text_.find_first_not_of(" \t\r\n"), text_.size());
    const std::string_view first = text_.substr(start, text_.find_first_of("\r\n", start) - start);
    if (first.find(',') == std::string_view::npos) {
      if (first.find(';') != std::string_view::npos)
        delimiter_ = ';';
      else if (first.find('\t') != std::string_view::npos)
        delimiter_ = '\t';
    }
  }
  check_encoding();

  std::vector<std::string_view> lines;
  for (std::size_t i = 0; i <= text_.size();) {
    const std::size_t eol = std::min(text_.find_first_of("\r\n", i), text_.size());
    lines.push_back(text_.substr(i, eol - i));
    if (eol == text_.size()) break;
    i = eol + ((text_[eol] == '\r' && eol + 1 < text_.size() && text_[eol + 1] == '\n') ? 2 : 1);
    if (i == text_.size()) break;  // a final line end does not start another line
  }
  const auto blank = [](std::string_view l) { return trim(l).empty(); };

  std::size_t h = 0;
  while (h < lines.size() && blank(lines[h])) ++h;
  if (h == lines.size())
    fail(1, 0, "empty file, expected a header row naming the columns (time, displacement, force)");
  const long header_line = static_cast<long>(h) + 1;

  std::vector<std::string> cells;
  split(lines[h], header_line, cells);
  header_ = cells;
  {
    std::string why;
    const bool numeric = std::all_of(cells.begin(), cells.end(), [&](const std::string& c) {
      return parse_number(c, why).has_value() || lower(c) == "nan" || lower(c) == "inf";
    });
    if (numeric)
      fail(header_line, 0,
           "no header row: the first row holds numbers, expected column names such as time, "
           "displacement, force");
  }
  resolve_columns(header_, header_line);

  const Units& u = options_.units;
  const std::array<double, kRoles> factor = {u.time, u.displacement, u.force, u.normal};
  std::array<std::vector<double>, kRoles> values;
  long first_data_line = 0;
  long pending_blank = 0;  // first blank line since the last data row
  long last_data_line = header_line;
  for (std::size_t k = h + 1; k < lines.size(); ++k) {
    const long line_no = static_cast<long>(k) + 1;
    if (blank(lines[k])) {
      if (pending_blank == 0) pending_blank = line_no;
      continue;
    }
    if (pending_blank != 0)
      fail(pending_blank, 0,
           "blank line between data rows, expected a data row (blank lines are allowed only at "
           "the end)");
    split(lines[k], line_no, cells);
    if (cells.size() != header_.size())
      fail(line_no, static_cast<long>(std::min(cells.size(), header_.size()) + 1),
           "the row has " + std::to_string(cells.size()) + " cells but the header has " +
               std::to_string(header_.size()) + ", expected " + std::to_string(header_.size()) +
               " cells separated by " +
               (delimiter_ == '\t' ? std::string("tabs") : shown(std::string(1, delimiter_))));
    if (first_data_line == 0) first_data_line = line_no;
    last_data_line = line_no;
    for (int r = 0; r < kRoles; ++r) {
      const int c = column_[r];
      if (c < 0) continue;
      std::string why;
      const auto v = parse_number(cells[c], why);
      if (!v) fail(line_no, c + 1, column_label(c) + ": " + why);
      const double si = *v * factor[r];
      if (!std::isfinite(si))
        fail(line_no, c + 1,
             column_label(c) + ": " + shown(cells[c]) +
                 " overflows a double after unit conversion, expected a smaller value");
      if (r == kTime && !values[kTime].empty() && !(si > values[kTime].back()))
        fail(line_no, c + 1,
             column_label(c) + ": time " + cells[c] + " is not greater than the time on line " +
                 std::to_string(line_no - 1) + ", expected strictly increasing time");
      values[r].push_back(si);
    }
  }

  const std::size_t n = values[kTime].size();
  if (n < std::max<std::size_t>(options_.min_samples, 2))
    fail(last_data_line, 0,
         "only " + std::to_string(n) + " sample" + (n == 1 ? "" : "s") + ", expected at least " +
             std::to_string(std::max<std::size_t>(options_.min_samples, 2)));
  if (options_.require_motion) {
    const auto& x = values[kDisplacement];
    if (std::all_of(x.begin(), x.end(), [&](double a) { return a == x.front(); }))
      fail(first_data_line, column_[kDisplacement] + 1,
           column_label(column_[kDisplacement]) + ": the displacement is constant (" +
               format_double(x.front()) + " m) over all " + std::to_string(n) +
               " samples, expected motion");
  }

  // Grown by doubling: up to half of each column would stay allocated, unused, for as long as
  // the record lives (a diagnosis keeps two).
  for (auto& v : values) v.shrink_to_fit();
  Record rec;
  rec.time = std::move(values[kTime]);
  rec.displacement = std::move(values[kDisplacement]);
  rec.force = std::move(values[kForce]);
  rec.normal = std::move(values[kNormal]);
  rec.source = name_;
  rec.first_line = first_data_line;
  std::array<std::string*, kRoles> col_names = {&rec.time_column, &rec.displacement_column,
                                                &rec.force_column, &rec.normal_column};
  for (int r = 0; r < kRoles; ++r)
    if (column_[r] >= 0) *col_names[r] = header_[column_[r]];
  condition_record(rec, {options_.force_sign, options_.period_tolerance});
  return rec;
}

}  // namespace

// ---------------------------------------------------------------- option parsing

ColumnMapping parse_column_mapping(std::string_view spec) {
  ColumnMapping m;
  std::array<std::string*, kRoles> slot = {&m.time, &m.displacement, &m.force, &m.normal};
  for (const auto& [key, value] : key_values(spec, "--columns")) {
    const auto role = role_of_key(key);
    if (!role)
      throw OptionError("--columns: unknown signal " + shown(key) +
                        ", expected time, displacement, force or normal");
    if (!slot[*role]->empty())
      throw OptionError("--columns: " + std::string(kRoleName[*role]) + " is given twice");
    std::string_view name = value;
    if (name.size() >= 2 && name.front() == '"' && name.back() == '"')
      name = trim(name.substr(1, name.size() - 2));
    if (name.empty()) throw OptionError("--columns: empty column name for " + std::string(key));
    *slot[*role] = std::string(name);
  }
  return m;
}

double unit_factor(std::string_view quantity, std::string_view unit) {
  const auto role = role_of_key(quantity);
  if (!role)
    throw OptionError("--units: unknown signal " + shown(quantity) +
                      ", expected time, displacement, force or normal");
  const auto& table =
      *role == kTime ? kTimeUnits : (*role == kDisplacement ? kLengthUnits : kForceUnits);
  const std::string_view u = trim(unit);
  std::vector<std::string_view> accepted;
  for (const auto& e : table) {
    if (e.symbol.empty()) continue;
    if (e.symbol == u) return e.factor;
    if (static_cast<unsigned char>(e.symbol.front()) < 0x80) accepted.push_back(e.symbol);
  }
  throw OptionError("--units: unknown unit " + shown(u) + " for " + kRoleName[*role] +
                    ", expected " + list(accepted));
}

Units parse_units(std::string_view spec) {
  Units u;
  std::array<double*, kRoles> slot = {&u.time, &u.displacement, &u.force, &u.normal};
  std::array<bool, kRoles> seen{};
  for (const auto& [key, value] : key_values(spec, "--units")) {
    const double f = unit_factor(key, value);
    const Role r = *role_of_key(key);
    if (seen[r]) throw OptionError("--units: " + std::string(kRoleName[r]) + " is given twice");
    seen[r] = true;
    *slot[r] = f;
  }
  return u;
}

ForceSign parse_force_sign(std::string_view text) {
  const std::string t = lower(trim(text));
  if (t == "auto" || t == "automatic") return ForceSign::automatic;
  if (t == "+1" || t == "1" || t == "positive" || t == "+") return ForceSign::positive;
  if (t == "-1" || t == "negative" || t == "-") return ForceSign::negative;
  throw OptionError("--force-sign: expected +1, -1 or auto, got " + shown(text));
}

// ---------------------------------------------------------------- reading entry points

Record read_record_text(std::string_view text, const std::string& name,
                        const ReadOptions& options) {
  return Reader(text, name, options).read();
}

Record read_record(std::istream& in, const std::string& name, const ReadOptions& options) {
  std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) throw DataError(name, 0, 0, "cannot read the input");
  return read_record_text(text, name, options);
}

Record read_record(const std::filesystem::path& path, const ReadOptions& options) {
  const std::string name = path.string();
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw DataError(name, 0, 0, "is a directory, expected a CSV file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DataError(name, 0, 0, std::string("cannot open: ") + std::strerror(errno));
  return read_record(in, name, options);
}

// ---------------------------------------------------------------- writing

std::string format_double(double value) {
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, value);
  FRICTION_ASSERT(ec == std::errc());
  return std::string(buf, ptr);
}

void write_csv(std::ostream& out, std::span<const CsvColumn> columns) {
  FRICTION_CHECK(!columns.empty(), "write_csv: no columns");
  const std::size_t n = columns.front().values.size();
  for (const auto& c : columns)
    FRICTION_CHECK(c.values.size() == n, "write_csv: column '", c.name, "' has ", c.values.size(),
                   " values, expected ", n);
  std::string buf;
  for (std::size_t j = 0; j < columns.size(); ++j) {
    if (j > 0) buf += ',';
    const std::string& name = columns[j].name;
    if (name.find_first_of(",\"\r\n") != std::string::npos || trim(name) != name) {
      buf += '"';
      for (char ch : name) buf += ch == '"' ? std::string("\"\"") : std::string(1, ch);
      buf += '"';
    } else {
      buf += name;
    }
  }
  buf += '\n';
  char num[64];
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t j = 0; j < columns.size(); ++j) {
      if (j > 0) buf += ',';
      const auto [ptr, ec] = std::to_chars(num, num + sizeof num, columns[j].values[k]);
      buf.append(num, ptr);
    }
    buf += '\n';
    if (buf.size() > (1u << 16)) {
      out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
      buf.clear();
    }
  }
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
}

void write_csv_file(const std::filesystem::path& path, std::span<const CsvColumn> columns) {
  write_file_atomically(path, [&](std::ostream& out) { write_csv(out, columns); });
}

std::vector<CsvColumn> record_columns(const Record& record) {
  std::vector<CsvColumn> c = {{"time", record.time}, {"displacement", record.measured()}};
  if (record.has_force()) c.push_back({"force", record.force});
  if (record.has_normal()) c.push_back({"normal", record.normal});
  return c;
}

void write_record_csv(std::ostream& out, const Record& record) {
  write_csv(out, record_columns(record));
}

void write_record_csv(const std::filesystem::path& path, const Record& record) {
  write_csv_file(path, record_columns(record));
}

}  // namespace friction
