#include "deformable_collision/core/common/enum_names.h"

#include <gtest/gtest.h>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/demo_scenes.h"

namespace deformable_collision {
namespace {

enum class Colour { kRed, kGreen, kBlue };
constexpr EnumNames<Colour, 3> kColourNames{
    {{Colour::kRed, "red"}, {Colour::kGreen, "green"}, {Colour::kBlue, "blue"}}};

TEST(EnumNames, ParsesEveryNameAndNothingElse) {
  EXPECT_EQ(parseEnum(kColourNames, "red"), Colour::kRed);
  EXPECT_EQ(parseEnum(kColourNames, "blue"), Colour::kBlue);
  EXPECT_FALSE(parseEnum(kColourNames, "Red"));
  EXPECT_FALSE(parseEnum(kColourNames, "re"));
  EXPECT_FALSE(parseEnum(kColourNames, ""));
}

TEST(EnumNames, ValueOutsideTheTableIsUnknown) {
  EXPECT_STREQ(enumName(kColourNames, Colour::kGreen), "green");
  EXPECT_STREQ(enumName(kColourNames, static_cast<Colour>(7)), "unknown");
}

TEST(EnumNames, ListJoinsNamesForAMessage) {
  EXPECT_EQ(enumNameList(kColourNames), "red, green or blue");
  constexpr EnumNames<Colour, 1> one{{{Colour::kRed, "red"}}};
  EXPECT_EQ(enumNameList(one), "red");
}

// Every table the package parses configuration with prints each value back to the name that
// parses to it.
template <typename Enum, std::size_t Count>
void expectRoundTrip(const EnumNames<Enum, Count>& names) {
  for (const auto& [value, name] : names) {
    EXPECT_EQ(parseEnum(names, enumName(names, value)), value) << name;
  }
}

TEST(EnumNames, PackageTablesRoundTrip) {
  expectRoundTrip(kObjectKindNames);
  expectRoundTrip(kDeformationModeNames);
  expectRoundTrip(kDemoSceneNames);
  EXPECT_STREQ(toString(DeformationMode::kQuadratic), "quadratic");
  EXPECT_EQ(parseObjectKind("kinematic"), ObjectKind::kKinematic);
  EXPECT_EQ(parseDemoScene("pile"), DemoScene::kPile);
  EXPECT_FALSE(parseDeformationMode("affine"));
}

}  // namespace
}  // namespace deformable_collision
