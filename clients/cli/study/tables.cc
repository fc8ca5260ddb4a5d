#include "clients/cli/study/tables.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <ostream>

#include "model/evaluation.h"

namespace fesbench::cli::study {
namespace {

std::string CsvCell(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

}  // namespace

std::string Num(double value, int digits) {
  if (!std::isfinite(value)) return "n/a";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, value);
  return buffer;
}

void WriteTable(const std::filesystem::path& dir, const Table& table, std::ostream& markdown) {
  std::ofstream csv(dir / (table.name + ".csv"));
  for (std::size_t i = 0; i < table.header.size(); ++i)
    csv << (i ? "," : "") << CsvCell(table.header[i]);
  csv << "\n";
  for (const auto& row : table.rows) {
    for (std::size_t i = 0; i < row.size(); ++i) csv << (i ? "," : "") << CsvCell(row[i]);
    csv << "\n";
  }
  markdown << "## " << table.title << "\n\n";
  if (!table.note.empty()) markdown << table.note << "\n\n";
  markdown << "|";
  for (const auto& h : table.header) markdown << " " << h << " |";
  markdown << "\n|";
  for (std::size_t i = 0; i < table.header.size(); ++i) markdown << "---|";
  markdown << "\n";
  for (const auto& row : table.rows) {
    markdown << "|";
    for (const auto& c : row) markdown << " " << c << " |";
    markdown << "\n";
  }
  markdown << "\n";
}

double Mean(const std::vector<double>& v) {
  double sum = 0.0;
  std::size_t n = 0;
  for (double x : v)
    if (std::isfinite(x)) sum += x, ++n;
  return n ? sum / static_cast<double>(n) : kNaN;
}
double Sd(const std::vector<double>& v) {
  const double m = Mean(v);
  double ss = 0.0;
  std::size_t n = 0;
  for (double x : v)
    if (std::isfinite(x)) ss += (x - m) * (x - m), ++n;
  return n > 1 ? std::sqrt(ss / static_cast<double>(n - 1)) : kNaN;
}

double Median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  const std::size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

double Worst(const std::vector<double>& v) {
  double worst = kNaN;
  for (double x : v)
    if (std::isfinite(x) && !(std::abs(x) <= std::abs(worst))) worst = x;
  return worst;
}

std::vector<std::string> TTestCells(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<std::string> row = {std::to_string(a.size()), Num(Mean(a)), Num(Mean(b))};
  if (a.size() < 2 || a.size() != b.size()) {
    for (int i = 0; i < 7; ++i) row.push_back("n/a");
    return row;
  }
  const model::PairedTTestResult t = model::PairedTTest(a, b, 0.95);
  for (double v : {t.mean_difference, t.sd_difference, t.t, t.df, t.p_value, t.t_critical})
    row.push_back(Num(v));
  row.push_back(!std::isfinite(t.t) ? "n/a" : (t.significant ? "yes" : "no"));
  return row;
}

}  // namespace fesbench::cli::study
