#pragma once

/// @file
/// The study's tables: Markdown for study.md, one CSV each, and the
/// statistics their cells hold (over the finite values; NaN shows "n/a").

#include <filesystem>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

namespace fesbench::cli::study {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Table {
  std::string name, title;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::string note;
};

/// `value` with `digits` decimals, "n/a" when not finite.
std::string Num(double value, int digits = 4);

/// Writes dir/<name>.csv and appends the table to `markdown`.
void WriteTable(const std::filesystem::path& dir, const Table& table, std::ostream& markdown);

double Mean(const std::vector<double>& v);
/// Sample standard deviation (n − 1).
double Sd(const std::vector<double>& v);
double Median(std::vector<double> v);
/// The finite value of largest magnitude (sign kept).
double Worst(const std::vector<double>& v);

/// The cells n, mean_a, mean_b, mean_diff, sd_diff, t, df, p, t_crit_95,
/// significant of a paired t-test (Eq. 6.3, model::PairedTTest) of a
/// against b (equal lengths); "n/a" from the mean difference on with
/// fewer than two pairs.
std::vector<std::string> TTestCells(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace fesbench::cli::study
