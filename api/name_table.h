#pragma once

/// @file
/// The wire names of an enumeration in one table, read both ways: the name
/// of a value and the value of a name. Each vocabulary of api/ (run states,
/// job states, step phases, event kinds, error codes) keeps its names in
/// one of these, so a name cannot be spelt two ways.

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fesbench::api {

template <typename Enum, std::size_t N>
class NameTable {
 public:
  using Entry = std::pair<Enum, std::string_view>;

  /// Every value once, each with its own name; `fallback` names a value
  /// missing from the table (never, for a complete table).
  constexpr NameTable(std::array<Entry, N> entries, std::string_view fallback)
      : entries_(entries), fallback_(fallback) {}

  constexpr std::string_view Name(Enum value) const {
    for (const auto& [v, name] : entries_) {
      if (v == value) return name;
    }
    return fallback_;
  }

  /// Every name, in the table's order (a command line's choices).
  std::vector<std::string> Names() const {
    std::vector<std::string> names;
    for (const auto& entry : entries_) names.emplace_back(entry.second);
    return names;
  }

  /// The value named exactly `name`, or nullopt.
  constexpr std::optional<Enum> Parse(std::string_view name) const {
    for (const auto& [v, n] : entries_) {
      if (n == name) return v;
    }
    return std::nullopt;
  }

 private:
  std::array<Entry, N> entries_;
  std::string_view fallback_;
};

}  // namespace fesbench::api
