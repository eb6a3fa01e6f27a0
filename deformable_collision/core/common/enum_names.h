#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace deformable_collision {

/// Every value of an enum with the name configuration files and messages use for it. One
/// table per enum serves both directions, so a name cannot be parsed one way and printed
/// another.
template <typename Enum, std::size_t Count>
using EnumNames = std::array<std::pair<Enum, const char*>, Count>;

/// The value named `name`; std::nullopt if the table has no such name.
template <typename Enum, std::size_t Count>
std::optional<Enum> parseEnum(const EnumNames<Enum, Count>& names, std::string_view name) {
  for (const auto& [value, value_name] : names) {
    if (name == value_name) return value;
  }
  return std::nullopt;
}

/// The name of `value`; "unknown" for a value outside the table (a cast of another number).
template <typename Enum, std::size_t Count>
const char* enumName(const EnumNames<Enum, Count>& names, Enum value) {
  for (const auto& [table_value, value_name] : names) {
    if (table_value == value) return value_name;
  }
  return "unknown";
}

/// The names joined for an error message: "a, b or c".
template <typename Enum, std::size_t Count>
std::string enumNameList(const EnumNames<Enum, Count>& names) {
  std::string list;
  for (std::size_t i = 0; i < Count; ++i) {
    if (i > 0) list += i + 1 == Count ? " or " : ", ";
    list += names[i].second;
  }
  return list;
}

}  // namespace deformable_collision
