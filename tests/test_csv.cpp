// Reading and writing records as CSV (cli.md "Inputs"): quirks read as intended, bad input refused
// with a DataError that names the file, line and column, exact round trips, atomic writes.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "friction/atomic_file.hpp"
#include "friction/csv.hpp"

namespace fs = std::filesystem;
using friction::DataError;
using friction::ForceSign;
using friction::ReadOptions;
using friction::Record;

namespace test_csv {
namespace {

// A plain record of `n` rows: time = 0.01 k, x = 1e-3 sin(0.5 k), F = 0.5 cos(0.5 k) (so F·v > 0).
std::vector<std::vector<std::string>> good_rows(int n = 12) {
  std::vector<std::vector<std::string>> rows;
  for (int k = 0; k < n; ++k)
    rows.push_back({friction::format_double(0.01 * k),
                    friction::format_double(1e-3 * std::sin(0.5 * k)),
                    friction::format_double(0.5 * std::cos(0.5 * k))});
  return rows;
}

std::string table(const std::string& header, const std::vector<std::vector<std::string>>& rows,
                  const std::string& eol = "\n") {
  std::string s = header + eol;
  for (const auto& r : rows) {
    for (std::size_t j = 0; j < r.size(); ++j) s += (j ? "," : "") + r[j];
    s += eol;
  }
  return s;
}

ReadOptions keep_sign() {
  ReadOptions o;
  o.force_sign = ForceSign::positive;
  return o;
}

// Expects a DataError whose message names bad.csv, `line` and, when > 0, `column`; returns it.
std::string expect_data_error(const std::string& text, long line, long column,
                              const ReadOptions& options = keep_sign()) {
  try {
    friction::read_record_text(text, "bad.csv", options);
  } catch (const DataError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), "bad.csv") << what;
    EXPECT_EQ(e.line(), line) << what;
    if (column > 0) {
      EXPECT_EQ(e.column(), column) << what;
    }
    std::string where = "bad.csv:" + std::to_string(line);
    if (column > 0) where += ":" + std::to_string(column);
    EXPECT_EQ(what.rfind(where + ":", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << "one line: " << what;
    return what;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected DataError, got: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected DataError, nothing thrown";
  return {};
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// A fresh directory under the system temp dir, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = fs::temp_directory_path() / ("friction_csv_test_" + std::to_string(rd()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(path_)) names.push_back(e.path().filename());
    return names;
  }

 private:
  fs::path path_;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// ------------------------------------------------------------------ reading good input

TEST(CsvRead, PlainRecordExactValues) {
  const auto rows = good_rows();
  const Record r =
      friction::read_record_text(table("time,displacement,force", rows), "ok.csv", keep_sign());
  ASSERT_EQ(r.size(), rows.size());
  for (int k = 0; k < static_cast<int>(rows.size()); ++k) {
    EXPECT_EQ(r.time[k], 0.01 * k);
    EXPECT_EQ(r.displacement[k], 1e-3 * std::sin(0.5 * k));
    EXPECT_EQ(r.force[k], 0.5 * std::cos(0.5 * k));
  }
  EXPECT_FALSE(r.has_normal());
  EXPECT_EQ(r.source, "ok.csv");
  EXPECT_EQ(r.first_line, 2);
  EXPECT_EQ(r.line_of(3), 5);
  EXPECT_EQ(r.time_column, "time");
}

TEST(CsvRead, HeaderAliasesAreCaseInsensitive) {
  const auto rows = good_rows();
  for (const std::string header :
       {"T,X,F", "Time_s,Position_M,Friction_Force_N", "time,position,friction"}) {
    const Record r = friction::read_record_text(table(header, rows), "ok.csv", keep_sign());
    EXPECT_EQ(r.size(), rows.size()) << header;
    EXPECT_EQ(r.force[1], 0.5 * std::cos(0.5)) << header;
  }
}

TEST(CsvRead, ByteOrderMarkAndCrlf) {
  const auto rows = good_rows();
  const Record r = friction::read_record_text(
      "\xEF\xBB\xBF" + table("time,displacement,force", rows, "\r\n"), "ok.csv", keep_sign());
  ASSERT_EQ(r.size(), rows.size());
  EXPECT_EQ(r.time_column, "time");  // not "\xEF\xBB\xBFtime"
  EXPECT_EQ(r.force.back(), 0.5 * std::cos(0.5 * 11));
}

TEST(CsvRead, QuotedHeaderAndQuotedCells) {
  const std::string text =
      table("\"time\",\"displacement\", \"force\"", {{"\"0\"", "\"0.5\"", " \"1.25\" "},
                                                     {"0.1", "0.75", "2"},
                                                     {"0.2", "1", "3"},
                                                     {"0.3", "0.5", "-1"},
                                                     {"0.4", "0.25", "-2"},
                                                     {"0.5", "0", "-3"},
                                                     {"0.6", "0.25", "1"},
                                                     {"0.7", "0.5", "2"},
                                                     {"0.8", "0.75", "3"},
                                                     {"0.9", "1", "4"}});
  const Record r = friction::read_record_text(text, "ok.csv", keep_sign());
  ASSERT_EQ(r.size(), 10u);
  EXPECT_EQ(r.displacement[0], 0.5);
  EXPECT_EQ(r.force[0], 1.25);
  EXPECT_EQ(r.time[9], 0.9);
}

TEST(CsvRead, SpacesAfterCommasExtraAndReorderedColumns) {
  std::string text = "comment, Force ,  index,Position,Time\n";
  for (int k = 0; k < 10; ++k)
    text += "note " + std::to_string(k) + ",  " + std::to_string(k - 4) + " , " +
            std::to_string(k) + ",\t" + std::to_string(k % 3) + ",  " + std::to_string(k) + "\n";
  const Record r = friction::read_record_text(text, "ok.csv", keep_sign());
  ASSERT_EQ(r.size(), 10u);
  for (int k = 0; k < 10; ++k) {
    EXPECT_EQ(r.time[k], k);
    EXPECT_EQ(r.displacement[k], k % 3);
    EXPECT_EQ(r.force[k], k - 4);
  }
  EXPECT_EQ(r.force_column, "Force");
  EXPECT_EQ(r.displacement_column, "Position");
}

TEST(CsvRead, TrailingBlankLinesAndNoFinalNewline) {
  const auto rows = good_rows();
  const std::string body = table("time,displacement,force", rows);
  EXPECT_EQ(friction::read_record_text(body + "\n\n  \n\r\n", "ok.csv", keep_sign()).size(),
            rows.size());
  EXPECT_EQ(
      friction::read_record_text(body.substr(0, body.size() - 1), "ok.csv", keep_sign()).size(),
      rows.size());
}

TEST(CsvRead, AllQuirksTogether) {
  std::string text = "\xEF\xBB\xBF\"Extra\", \"FORCE\" ,\"time_s\", \"x\"\r\n";
  for (int k = 0; k < 10; ++k)
    text += "a, \"" + std::to_string(k) + ".5\", " + std::to_string(k) + "e-3 ,\"" +
            (k % 2 ? "1" : "-1") + "\"\r\n";
  text += "\r\n\r\n";
  const Record r = friction::read_record_text(text, "ok.csv", keep_sign());
  ASSERT_EQ(r.size(), 10u);
  EXPECT_EQ(r.time[7], 7e-3);
  EXPECT_EQ(r.force[3], 3.5);
  EXPECT_EQ(r.displacement[2], -1.0);
}

TEST(CsvRead, SemicolonAndTabSeparators) {
  std::string semi = "time;x;force\n", tab = "time\tx\tforce\n";
  for (int k = 0; k < 10; ++k) {
    semi += std::to_string(k) + ";" + std::to_string(k % 2) + ";1.5\n";
    tab += std::to_string(k) + "\t" + std::to_string(k % 2) + "\t1.5\n";
  }
  EXPECT_EQ(friction::read_record_text(semi, "ok.csv", keep_sign()).displacement[1], 1.0);
  EXPECT_EQ(friction::read_record_text(tab, "ok.csv", keep_sign()).displacement[1], 1.0);
}

TEST(CsvRead, NormalColumnOptionalAndForceOptionalWhenNotRequired) {
  std::string text = "time,x,force,normal_force_n\n";
  for (int k = 0; k < 10; ++k)
    text += std::to_string(k) + "," + std::to_string(k % 2) + ",1," + std::to_string(5 + k) + "\n";
  const Record r = friction::read_record_text(text, "ok.csv", keep_sign());
  ASSERT_TRUE(r.has_normal());
  EXPECT_EQ(r.normal[4], 9.0);
  EXPECT_EQ(r.normal_column, "normal_force_n");

  std::string no_force = "time,x\n";
  for (int k = 0; k < 10; ++k) no_force += std::to_string(k) + "," + std::to_string(k % 2) + "\n";
  ReadOptions o;
  o.require_force = false;
  const Record s = friction::read_record_text(no_force, "ok.csv", o);
  EXPECT_FALSE(s.has_force());
  EXPECT_EQ(s.size(), 10u);
  // ... but it is required by default.
  EXPECT_THROW(friction::read_record_text(no_force, "ok.csv"), DataError);
}

TEST(CsvRead, UnitsConvertToSi) {
  const friction::Units u = friction::parse_units("displacement=mm,force=uN,time=ms,normal=N");
  EXPECT_EQ(u.displacement, 1e-3);
  EXPECT_EQ(u.force, 1e-6);
  EXPECT_EQ(u.time, 1e-3);
  EXPECT_EQ(u.normal, 1.0);
  EXPECT_EQ(friction::unit_factor("displacement", "um"), 1e-6);
  EXPECT_EQ(friction::unit_factor("displacement", "\xC2\xB5m"), 1e-6);
  EXPECT_EQ(friction::unit_factor("displacement", "nm"), 1e-9);
  EXPECT_EQ(friction::unit_factor("time", "us"), 1e-6);
  EXPECT_EQ(friction::unit_factor("time", "s"), 1.0);
  EXPECT_EQ(friction::unit_factor("force", "kN"), 1e3);
  EXPECT_EQ(friction::unit_factor("force", "mN"), 1e-3);
  EXPECT_EQ(friction::unit_factor("normal", "uN"), 1e-6);

  std::string text = "time,x,force,normal\n";
  for (int k = 0; k < 10; ++k)
    text += std::to_string(5 * k) + "," + std::to_string(k % 2) + ".5,250,3\n";
  ReadOptions o = keep_sign();
  o.units = friction::parse_units("displacement=mm,force=uN,time=ms,normal=mN");
  const Record r = friction::read_record_text(text, "ok.csv", o);
  EXPECT_DOUBLE_EQ(r.time[3], 15e-3);
  EXPECT_DOUBLE_EQ(r.displacement[1], 1.5e-3);
  EXPECT_DOUBLE_EQ(r.force[0], 250e-6);
  EXPECT_DOUBLE_EQ(r.normal[0], 3e-3);
  EXPECT_DOUBLE_EQ(r.conditioning.nominal_period, 5e-3);
}

TEST(CsvRead, BadUnitsAndMappingsAreOptionErrors) {
  using friction::OptionError;
  EXPECT_THROW(friction::parse_units("displacement=furlong"), OptionError);
  EXPECT_THROW(friction::parse_units("speed=mm"), OptionError);
  EXPECT_THROW(friction::parse_units("force=MN"), OptionError);  // symbols are case-sensitive
  EXPECT_THROW(friction::parse_units("force"), OptionError);
  EXPECT_THROW(friction::parse_units("force=N,force=mN"), OptionError);
  EXPECT_THROW(friction::parse_units(""), OptionError);
  EXPECT_THROW(friction::parse_column_mapping("time=a,velocity=b"), OptionError);
  EXPECT_THROW(friction::parse_column_mapping("time="), OptionError);
  EXPECT_THROW(friction::parse_column_mapping("time=a,time=b"), OptionError);
  try {
    friction::parse_units("displacement=furlong");
  } catch (const OptionError& e) {
    EXPECT_TRUE(contains(e.what(), "furlong") && contains(e.what(), "mm")) << e.what();
  }
  EXPECT_EQ(friction::parse_force_sign("auto"), ForceSign::automatic);
  EXPECT_EQ(friction::parse_force_sign("+1"), ForceSign::positive);
  EXPECT_EQ(friction::parse_force_sign("-1"), ForceSign::negative);
  EXPECT_THROW(friction::parse_force_sign("2"), OptionError);
}

TEST(CsvRead, ExplicitColumnMapping) {
  const friction::ColumnMapping m =
      friction::parse_column_mapping("time=Zeit, displacement=Weg,force=Kraft,normal=Last");
  EXPECT_EQ(m.time, "Zeit");
  EXPECT_EQ(m.displacement, "Weg");
  EXPECT_EQ(m.force, "Kraft");
  EXPECT_EQ(m.normal, "Last");
  // The header also has columns that the aliases would pick ("x", "force"): the mapping wins.
  std::string text = "x,force,zeit,weg,kraft,last\n";
  for (int k = 0; k < 10; ++k)
    text += "7,8," + std::to_string(k) + "," + std::to_string(k % 2) + "," +
            std::to_string(k + 100) + ",4\n";
  ReadOptions o = keep_sign();
  o.columns = m;
  const Record r = friction::read_record_text(text, "ok.csv", o);
  EXPECT_EQ(r.time[2], 2.0);
  EXPECT_EQ(r.displacement[1], 1.0);
  EXPECT_EQ(r.force[3], 103.0);
  EXPECT_EQ(r.normal[0], 4.0);
  EXPECT_EQ(r.time_column, "zeit");

  o.columns = friction::parse_column_mapping("time=zeit,displacement=weg,force=nope");
  const std::string what = expect_data_error(text, 1, 0, o);
  EXPECT_TRUE(contains(what, "'nope'")) << what;
}

TEST(CsvRead, ReadsFromStreamAndFile) {
  const std::string text = table("time,displacement,force", good_rows());
  std::istringstream in(text);
  EXPECT_EQ(friction::read_record(in, "stream", keep_sign()).size(), 12u);
  TempDir dir;
  const fs::path p = dir.path() / "r.csv";
  std::ofstream(p) << text;
  const Record r = friction::read_record(p, keep_sign());
  EXPECT_EQ(r.size(), 12u);
  EXPECT_EQ(r.source, p.string());
}

// ------------------------------------------------------------------ refusing bad input

TEST(CsvBad, MissingFileNamesTheFile) {
  try {
    friction::read_record(fs::path("/nonexistent/dir/missing.csv"));
    ADD_FAILURE() << "no exception";
  } catch (const DataError& e) {
    EXPECT_TRUE(contains(e.what(), "/nonexistent/dir/missing.csv")) << e.what();
  }
}

TEST(CsvBad, EmptyFile) {
  EXPECT_TRUE(contains(expect_data_error("", 1, 0), "empty"));
  EXPECT_TRUE(contains(expect_data_error("\n  \r\n", 1, 0), "empty"));
  EXPECT_TRUE(contains(expect_data_error("\xEF\xBB\xBF", 1, 0), "empty"));
}

TEST(CsvBad, NoHeaderRow) {
  auto rows = good_rows();
  std::string text;
  for (const auto& r : rows) text += r[0] + "," + r[1] + "," + r[2] + "\n";
  EXPECT_TRUE(contains(expect_data_error(text, 1, 0), "header"));
}

TEST(CsvBad, MissingRequiredColumnListsAcceptedNames) {
  const auto rows = good_rows();
  std::string what = expect_data_error(table("time,displacement,torque", rows), 1, 0);
  EXPECT_TRUE(contains(what, "force, friction, f or friction_force_n")) << what;
  EXPECT_TRUE(contains(what, "torque")) << what;  // says what the header has
  what = expect_data_error(table("zeit,displacement,force", rows), 1, 0);
  EXPECT_TRUE(contains(what, "time, t or time_s")) << what;
  what = expect_data_error(table("time,weg,force", rows), 1, 0);
  EXPECT_TRUE(contains(what, "displacement, position, x or position_m")) << what;
}

TEST(CsvBad, TwoColumnsForOneSignal) {
  std::string text = "time,x,position,force\n";
  for (int k = 0; k < 10; ++k) text += std::to_string(k) + ",1,2,3\n";
  const std::string what = expect_data_error(text, 1, 3);
  EXPECT_TRUE(contains(what, "'x'") && contains(what, "'position'")) << what;
}

TEST(CsvBad, NonNumericCell) {
  auto rows = good_rows();
  rows[3][2] = "abc";  // line 5 (header is line 1), column 3
  const std::string what = expect_data_error(table("time,displacement,force", rows), 5, 3);
  EXPECT_TRUE(contains(what, "'abc'") && contains(what, "expected a number")) << what;
  rows = good_rows();
  rows[6][1] = "1.5e";  // a number prefix is not enough: the whole cell must parse
  expect_data_error(table("time,displacement,force", rows), 8, 2);
  rows = good_rows();
  rows[6][1] = "0x10";
  expect_data_error(table("time,displacement,force", rows), 8, 2);
  rows = good_rows();
  rows[2][0] = "";  // empty cell
  EXPECT_TRUE(contains(expect_data_error(table("time,displacement,force", rows), 4, 1), "empty"));
}

TEST(CsvBad, NanAndInf) {
  for (const std::string bad : {"nan", "NaN", "inf", "-Infinity"}) {
    auto rows = good_rows();
    rows[5][1] = bad;
    const std::string what = expect_data_error(table("time,displacement,force", rows), 7, 2);
    EXPECT_TRUE(contains(what, "finite")) << what;
  }
}

TEST(CsvBad, OverflowingNumber) {
  auto rows = good_rows();
  rows[4][2] = "1e999";
  const std::string what = expect_data_error(table("time,displacement,force", rows), 6, 3);
  EXPECT_TRUE(contains(what, "range of a double")) << what;
  // Underflow is harmless: it reads as zero.
  rows = good_rows();
  rows[4][2] = "1e-400";
  EXPECT_EQ(
      friction::read_record_text(table("time,displacement,force", rows), "ok.csv", keep_sign())
          .force[4],
      0.0);
}

TEST(CsvBad, TimeNotStrictlyIncreasing) {
  auto rows = good_rows();
  rows[4][0] = rows[3][0];  // equal time on line 6
  std::string what = expect_data_error(table("time,displacement,force", rows), 6, 1);
  EXPECT_TRUE(contains(what, "strictly increasing")) << what;
  rows = good_rows();
  rows[8][0] = "0.01";  // going back on line 10
  expect_data_error(table("time,displacement,force", rows), 10, 1);
}

TEST(CsvBad, TooFewSamplesStatesTheMinimum) {
  const std::string what = expect_data_error(table("time,displacement,force", good_rows(4)), 5, 0);
  EXPECT_TRUE(contains(what, "at least 10")) << what;
  // A header alone: the header line is named.
  expect_data_error("time,displacement,force\n", 1, 0);
}

TEST(CsvBad, NoMotion) {
  auto rows = good_rows();
  for (auto& r : rows) r[1] = "-0.11";
  const std::string what = expect_data_error(table("time,displacement,force", rows), 2, 2);
  EXPECT_TRUE(contains(what, "constant")) << what;
}

TEST(CsvBad, RaggedRow) {
  auto rows = good_rows();
  rows[6].pop_back();  // line 8 has 2 cells
  std::string what = expect_data_error(table("time,displacement,force", rows), 8, 3);
  EXPECT_TRUE(contains(what, "2 cells") && contains(what, "header has 3")) << what;
  rows = good_rows();
  rows[2].push_back("9");  // line 4 has 4 cells
  expect_data_error(table("time,displacement,force", rows), 4, 4);
}

TEST(CsvBad, BlankLineBetweenDataRows) {
  const auto rows = good_rows();
  std::string text = table("time,displacement,force", {rows.begin(), rows.begin() + 5}) + "\n" +
                     table("", {rows.begin() + 5, rows.end()}).substr(1);
  EXPECT_TRUE(contains(expect_data_error(text, 7, 0), "blank line"));
}

TEST(CsvBad, UnterminatedQuote) {
  auto rows = good_rows();
  rows[1][2] = "\"1.5";
  expect_data_error(table("time,displacement,force", rows), 3, 3);
}

TEST(CsvBad, BinaryGarbage) {
  const std::string good = table("time,displacement,force", good_rows());
  const auto line_start = [&](int line) {  // offset of the first character of a 1-based line
    std::size_t pos = 0;
    for (int l = 1; l < line; ++l) pos = good.find('\n', pos) + 1;
    return pos;
  };
  std::string nul = good;
  nul.insert(line_start(3) + 1, 1, '\0');  // inside column 1 of line 3
  EXPECT_TRUE(contains(expect_data_error(nul, 3, 1), "NUL"));

  std::string utf = good;
  utf.insert(line_start(4), "0,\xFF");  // in column 2 of line 4
  EXPECT_TRUE(contains(expect_data_error(utf, 4, 2), "UTF-8"));

  std::string ctl = good;
  ctl[line_start(6)] = '\x01';
  EXPECT_TRUE(contains(expect_data_error(ctl, 6, 1), "control character"));

  std::string overlong = good;
  overlong.insert(line_start(2), "\xC0\xAF");  // overlong '/'
  expect_data_error(overlong, 2, 1);

  // A binary blob (PNG signature) is refused on its first line.
  EXPECT_TRUE(contains(expect_data_error(std::string("\x89PNG\r\n\x1A\n\0\0\0\rIHDR", 16), 1, 1),
                       "binary"));
}

TEST(CsvBad, ValidUtf8IsNotGarbage) {
  std::string text = "time,x,force,note\n";
  for (int k = 0; k < 10; ++k)
    text += std::to_string(k) + "," + std::to_string(k % 2) + ",1,\xC2\xB5m \xE2\x82\xAC\n";
  EXPECT_EQ(friction::read_record_text(text, "ok.csv", keep_sign()).size(), 10u);
}

// ------------------------------------------------------------------ writing

TEST(CsvWrite, FormatDoubleIsShortestAndRoundTrips) {
  EXPECT_EQ(friction::format_double(0.1), "0.1");
  EXPECT_EQ(friction::format_double(1e-7), "1e-07");
  EXPECT_EQ(friction::format_double(-2.5), "-2.5");
  EXPECT_EQ(friction::format_double(0.1 + 0.2), "0.30000000000000004");
}

TEST(CsvWrite, RoundTripIsExact) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Record r;
  double t = 0;
  for (int k = 0; k < 500; ++k) {
    t += 1e-3 * (1 + u(rng) * 0.3);
    r.time.push_back(t);
    r.displacement.push_back(-0.11 + 1e-4 * std::sin(0.05 * k) + 1e-9 * u(rng));
    r.force.push_back(std::ldexp(u(rng), static_cast<int>(k % 40) - 20));
    r.normal.push_back(k == 7 ? std::numeric_limits<double>::denorm_min() : 5 + u(rng));
  }
  r.force[3] = 1.0 / 3.0;
  r.force[4] = -0.0;
  r.force[5] = std::numeric_limits<double>::max();
  std::ostringstream out;
  friction::write_record_csv(out, r);
  EXPECT_EQ(out.str().rfind("time,displacement,force,normal\n", 0), 0u);
  const Record back = friction::read_record_text(out.str(), "mem", keep_sign());
  EXPECT_EQ(back.time, r.time);
  EXPECT_EQ(back.displacement, r.displacement);
  EXPECT_EQ(back.force, r.force);
  EXPECT_EQ(back.normal, r.normal);
  EXPECT_TRUE(std::signbit(back.force[4]));

  TempDir dir;
  const fs::path p = dir.path() / "record.csv";
  friction::write_record_csv(p, r);
  const Record from_file = friction::read_record(p, keep_sign());
  EXPECT_EQ(from_file.force, r.force);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"record.csv"});
}

TEST(CsvWrite, GeneralColumnsAndQuotedNames) {
  const std::vector<double> a = {1, 2}, b = {0.5, -0.25};
  const std::vector<friction::CsvColumn> cols = {{"time", a}, {"a,b \"q\"", b}};
  std::ostringstream out;
  friction::write_csv(out, cols);
  EXPECT_EQ(out.str(), "time,\"a,b \"\"q\"\"\"\n1,0.5\n2,-0.25\n");
  const std::vector<double> short_column = {1};
  const std::vector<friction::CsvColumn> bad = {{"time", a}, {"x", short_column}};
  EXPECT_THROW(friction::write_csv(out, bad), friction::InvalidParameter);
}

TEST(AtomicFile, ReplacesContentAndKeepsPermissions) {
  TempDir dir;
  const fs::path p = dir.path() / "out.json";
  friction::write_file_atomically(p, std::string_view("old\n"));
  ASSERT_EQ(::chmod(p.c_str(), 0640), 0);
  friction::write_file_atomically(p, std::string_view("new content\n"));
  EXPECT_EQ(slurp(p), "new content\n");
  struct stat st;
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"out.json"});
}

TEST(AtomicFile, FailingWriterLeavesOldFileAndNoTemporary) {
  TempDir dir;
  const fs::path p = dir.path() / "out.csv";
  friction::write_file_atomically(p, std::string_view("old content\n"));
  struct Boom {};
  EXPECT_THROW(friction::write_file_atomically(p,
                                               [](std::ostream& out) {
                                                 out << std::string(100000, 'x');  // half written
                                                 throw Boom{};
                                               }),
               Boom);
  EXPECT_EQ(slurp(p), "old content\n");
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"out.csv"});

  // A stream that goes bad is an I/O failure: FileError, old content kept.
  EXPECT_THROW(
      friction::write_file_atomically(p, [](std::ostream& out) { out.setstate(std::ios::badbit); }),
      friction::FileError);
  EXPECT_EQ(slurp(p), "old content\n");
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"out.csv"});

  // A failing record writer (unequal columns) leaves the old file too.
  Record bad;
  bad.time = {0, 1, 2};
  bad.displacement = {0, 1};
  EXPECT_THROW(friction::write_record_csv(p, bad), friction::InvalidParameter);
  EXPECT_EQ(slurp(p), "old content\n");
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"out.csv"});
}

TEST(AtomicFile, MissingDirectoryIsFileError) {
  TempDir dir;
  const fs::path p = dir.path() / "no" / "such" / "out.csv";
  try {
    friction::write_file_atomically(p, std::string_view("x"));
    ADD_FAILURE() << "no exception";
  } catch (const friction::FileError& e) {
    EXPECT_TRUE(contains(e.what(), p.string())) << e.what();
  }
  // The target being a directory: the rename is refused, nothing is left behind.
  EXPECT_THROW(friction::write_file_atomically(dir.path(), std::string_view("x")),
               friction::FileError);
}

}  // namespace
}  // namespace test_csv
