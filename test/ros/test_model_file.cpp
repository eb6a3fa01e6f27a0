#include "deformable_collision/ros/model_file.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <stdexcept>
#include <string>
#include <unistd.h>
#include <vector>

namespace deformable_collision {
namespace {

/// A fresh directory under /tmp for one test's files, removed with them afterwards.
class ModelFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char name[] = "/tmp/test_model_file_XXXXXX";
    ASSERT_NE(::mkdtemp(name), nullptr);
    directory_ = name;
  }
  void TearDown() override {
    for (const std::string& file : files_) ::unlink(file.c_str());
    ::rmdir(directory_.c_str());
  }
  std::string path(const std::string& file_name) {
    files_.push_back(directory_ + "/" + file_name);
    return files_.back();
  }
  std::string writeText(const std::string& file_name, const std::string& text) {
    const std::string file = path(file_name);
    std::ofstream(file, std::ios::binary) << text;
    return file;
  }

 private:
  std::string directory_;
  std::vector<std::string> files_;
};

std::vector<Eigen::Vector3d> samplePoints() {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 50; ++i) {
    points.emplace_back(0.01 * i - 0.2, 0.5 + 0.003 * i, -1.25 + 1e-4 * i * i);
  }
  return points;
}

/// `actual` equals `expected` point by point to float32 rounding.
void expectSamePoints(const std::vector<Eigen::Vector3d>& expected,
                      const std::vector<Eigen::Vector3d>& actual) {
  ASSERT_EQ(actual.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_LE((actual[i] - expected[i]).cwiseAbs().maxCoeff(), 1e-6) << "point " << i;
  }
}

/// The message of the exception `read` throws; fails the test if it throws none.
std::string errorOf(const std::function<void()>& read) {
  try {
    read();
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  ADD_FAILURE() << "no std::invalid_argument";
  return "";
}

std::string pcdHeader(const std::string& fields, int count, const std::string& data) {
  const std::string n = std::to_string(count);
  return "# .PCD v0.7\nVERSION 0.7\nFIELDS " + fields + "\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n" +
         "WIDTH " + n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\nDATA " + data +
         "\n";
}

TEST_F(ModelFileTest, PlyRoundTripKeepsOrderAndValues) {
  const std::string file = path("model.ply");
  writeModelFile(file, samplePoints());
  expectSamePoints(samplePoints(), readModelFile(file));
}

TEST_F(ModelFileTest, WrittenPlyIsBinaryLittleEndianFloat32) {
  const std::string file = path("one.ply");
  writeModelFile(file, {Eigen::Vector3d(1.0, -2.0, 0.5)});
  std::ifstream in(file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string header_end = "end_header\n";
  ASSERT_NE(bytes.find("format binary_little_endian 1.0\n"), std::string::npos);
  ASSERT_NE(bytes.find("property float x\n"), std::string::npos);
  const std::size_t body = bytes.find(header_end) + header_end.size();
  ASSERT_EQ(bytes.size() - body, 12u);
  // 1.0f, -2.0f, 0.5f: sign and exponent in each value's last byte.
  EXPECT_EQ(bytes.substr(body, 12),
            std::string("\x00\x00\x80\x3f\x00\x00\x00\xc0\x00\x00\x00\x3f", 12));
}

TEST_F(ModelFileTest, AsciiPcdDropsNonFinitePointsInOrder) {
  const std::string file = writeText(
      "model.PCD", pcdHeader("x y z", 4, "ascii") + "1 2 3\nnan nan nan\n4 5 6\n7 nan 9\n");
  expectSamePoints({Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(4, 5, 6)}, readModelFile(file));
}

TEST_F(ModelFileTest, BinaryPcdRoundTrip) {
  const std::vector<Eigen::Vector3d> points = samplePoints();
  std::string text = pcdHeader("x y z", static_cast<int>(points.size()), "binary");
  for (const Eigen::Vector3d& p : points) {
    const float xyz[3] = {float(p.x()), float(p.y()), float(p.z())};
    text.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
  }
  expectSamePoints(points, readModelFile(writeText("model.pcd", text)));
}

TEST_F(ModelFileTest, AsciiPlyOfDoublesWithMoreProperties) {
  const std::string file = writeText(
      "scan.ply",
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
      "property double z\nproperty uchar red\nend_header\n0.125 0.25 0.5 255\n-1 -2 -3 0\n");
  expectSamePoints({Eigen::Vector3d(0.125, 0.25, 0.5), Eigen::Vector3d(-1, -2, -3)},
                   readModelFile(file));
}

TEST_F(ModelFileTest, ErrorsNameThePathAndTheFault) {
  const std::string missing = path("missing.ply");
  EXPECT_EQ(errorOf([&] { readModelFile(missing); }), "model file '" + missing + "': no such file");

  const std::string obj = writeText("model.obj", "v 0 0 0\n");
  EXPECT_NE(errorOf([&] { readModelFile(obj); }).find("the extension must be .ply or .pcd"),
            std::string::npos);

  const std::string garbage = writeText("garbage.ply", "this is not a PLY file\n");
  const std::string unreadable = errorOf([&] { readModelFile(garbage); });
  EXPECT_NE(unreadable.find(garbage), std::string::npos);
  EXPECT_NE(unreadable.find("PCL could not read it as ply"), std::string::npos);

  const std::string no_xyz = writeText("abc.pcd", pcdHeader("a b c", 1, "ascii") + "1 2 3\n");
  EXPECT_NE(errorOf([&] { readModelFile(no_xyz); }).find("field 'x' is missing"),
            std::string::npos);

  const std::string all_nan =
      writeText("nan.pcd", pcdHeader("x y z", 2, "ascii") + "nan nan nan\n1 nan 2\n");
  EXPECT_NE(errorOf([&] { readModelFile(all_nan); }).find("has no point with finite x, y and z"),
            std::string::npos);
}

TEST_F(ModelFileTest, EmptyModelIsRefused) {
  const std::string file = path("empty.ply");
  writeModelFile(file, {});
  const std::string error = errorOf([&] { readModelFile(file); });
  EXPECT_EQ(error, "model file '" + file + "': has no point with finite x, y and z");
}

TEST_F(ModelFileTest, WritingRefusesNonFinitePointsAndBadPaths) {
  const std::string file = path("nan.ply");
  EXPECT_NE(errorOf([&] { writeModelFile(file, {Eigen::Vector3d(0, NAN, 0)}); }).find("not finite"),
            std::string::npos);
  EXPECT_NE(errorOf([&] {
              writeModelFile("/nonexistent_directory/m.ply", samplePoints());
            }).find("cannot be opened for writing"),
            std::string::npos);
}

}  // namespace
}  // namespace deformable_collision
