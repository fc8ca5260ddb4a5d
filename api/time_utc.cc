#include "api/time_utc.h"

#include <algorithm>
#include <cstdio>

namespace fesbench::api {
namespace {

using std::chrono::days;
using std::chrono::microseconds;

// Parses `count` decimal digits at text[pos]; nullopt on any non-digit.
std::optional<int> Digits(std::string_view text, std::size_t pos, std::size_t count) {
  if (pos + count > text.size()) return std::nullopt;
  int value = 0;
  for (std::size_t i = pos; i < pos + count; ++i) {
    if (text[i] < '0' || text[i] > '9') return std::nullopt;
    value = value * 10 + (text[i] - '0');
  }
  return value;
}

std::optional<std::chrono::year_month_day> ParseDate(std::string_view text) {
  if (text.size() < 10 || text[4] != '-' || text[7] != '-') return std::nullopt;
  const auto y = Digits(text, 0, 4);
  const auto m = Digits(text, 5, 2);
  const auto d = Digits(text, 8, 2);
  if (!y || !m || !d) return std::nullopt;
  const std::chrono::year_month_day ymd{std::chrono::year(*y),
                                        std::chrono::month(static_cast<unsigned>(*m)),
                                        std::chrono::day(static_cast<unsigned>(*d))};
  if (!ymd.ok()) return std::nullopt;
  return ymd;
}

}  // namespace

std::string FormatUtc(UtcTime t) {
  const auto day = std::chrono::floor<days>(t);
  const std::chrono::year_month_day ymd{day};
  const std::chrono::hh_mm_ss<microseconds> tod{t - day};
  const int year = std::clamp(static_cast<int>(ymd.year()), 0, 9999);
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%04d-%02u-%02uT%02d:%02d:%02d.%06lldZ", year,
                static_cast<unsigned>(ymd.month()), static_cast<unsigned>(ymd.day()),
                static_cast<int>(tod.hours().count()), static_cast<int>(tod.minutes().count()),
                static_cast<int>(tod.seconds().count()),
                static_cast<long long>(tod.subseconds().count()));
  return buffer;
}

std::optional<UtcTime> ParseUtc(std::string_view text) {
  // YYYY-MM-DDTHH:MM:SS.ffffffZ is 27 characters.
  if (text.size() != 27 || text[10] != 'T' || text[13] != ':' || text[16] != ':' ||
      text[19] != '.' || text[26] != 'Z') {
    return std::nullopt;
  }
  const auto ymd = ParseDate(text.substr(0, 10));
  const auto h = Digits(text, 11, 2);
  const auto mi = Digits(text, 14, 2);
  const auto s = Digits(text, 17, 2);
  const auto us = Digits(text, 20, 6);
  if (!ymd || !h || !mi || !s || !us || *h > 23 || *mi > 59 || *s > 59) return std::nullopt;
  return std::chrono::sys_days{*ymd} + std::chrono::hours(*h) + std::chrono::minutes(*mi) +
         std::chrono::seconds(*s) + microseconds(*us);
}

bool IsIsoDate(std::string_view text) { return text.size() == 10 && ParseDate(text).has_value(); }

}  // namespace fesbench::api
