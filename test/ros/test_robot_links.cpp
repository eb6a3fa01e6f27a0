// RobotLinks (ros/robot_links.h): a URDF's links' collision geometry (box, cylinder, sphere,
// an STL through file://, a COLLADA file through package://, collision origins, mesh scales,
// several collision elements) as surface points in the link's frame, checked against the
// true surfaces; and each way a link is refused, naming it.
#include "deformable_collision/ros/robot_links.h"

#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unistd.h>
#include <vector>

#include "../core/surface_test_support.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;
using test::Surface;

constexpr double kSpacing = 0.003;
/// Meshes come through assimp in single precision: their points are on the triangles to
/// float rounding of centimetre coordinates.
constexpr double kOnSurfaceM = 1e-8;

/// A collision origin as URDF reads it: rotation Rz(yaw) Ry(pitch) Rx(roll), then xyz.
Eigen::Isometry3d origin(const Eigen::Vector3d& xyz, const Eigen::Vector3d& rpy) {
  Eigen::Isometry3d pose(Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                         Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                         Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()));
  pose.translation() = xyz;
  return pose;
}

std::string originXml(const Eigen::Vector3d& xyz, const Eigen::Vector3d& rpy) {
  std::ostringstream out;
  out.precision(17);
  out << "<origin xyz=\"" << xyz.transpose() << "\" rpy=\"" << rpy.transpose() << "\"/>";
  return out.str();
}

// The links' collision origins.
const Eigen::Vector3d kBoxXyz(0.01, 0.0, 0.02), kBoxRpy(0.0, 0.0, 0.3);
const Eigen::Vector3d kCylinderXyz(0.0, 0.01, 0.0), kCylinderRpy(M_PI / 2, 0.0, 0.0);
const Eigen::Vector3d kSphereXyz(0.0, 0.0, 0.05), kZero(0.0, 0.0, 0.0);
const Eigen::Vector3d kStlXyz(0.005, 0.0, 0.0), kStlRpy(0.2, 0.1, 0.0);
const Eigen::Vector3d kDaeXyz(0.0, 0.0, 0.01), kDaeRpy(0.0, 0.0, 1.0);
const Eigen::Vector3d kPadXyz(0.0, 0.0, -0.02);

/// A tetrahedron's corners and faces (outwards), in the test meshes' units.
const Points kTetraCorners = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
const std::vector<std::array<std::uint32_t, 3>> kTetraFaces = {
    {0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};

/// The tetrahedron with corner i at `size` times kTetraCorners[i], then `place`d.
TriangleMesh tetra(const Eigen::Vector3d& size, const Eigen::Isometry3d& place) {
  TriangleMesh mesh;
  for (const Eigen::Vector3d& c : kTetraCorners)
    mesh.vertices.push_back(place * size.cwiseProduct(c));
  mesh.triangles = kTetraFaces;
  return mesh;
}

Surface meshSurface(const TriangleMesh& mesh) {
  return {[mesh](const Eigen::Vector3d& p) { return test::meshDistance(mesh, p); },
          [mesh](std::mt19937& r) { return test::drawOnMesh(mesh, r); }};
}

/// An ASCII STL of the tetrahedron of edges 20, 10 and 30 mm.
std::string wedgeStl() {
  const Eigen::Vector3d size(20, 10, 30);
  std::ostringstream out;
  out << "solid wedge\n";
  for (const auto& face : kTetraFaces) {
    out << "facet normal 0 0 0\n outer loop\n";
    for (const std::uint32_t i : face) {
      out << "  vertex " << size.cwiseProduct(kTetraCorners[i]).transpose() << "\n";
    }
    out << " endloop\nendfacet\n";
  }
  out << "endsolid wedge\n";
  return out.str();
}

std::string meshXml(const std::string& uri, const std::string& scale) {
  return "<mesh filename=\"" + uri + "\" scale=\"" + scale + "\"/>";
}

std::string linkXml(const std::string& name, const std::vector<std::string>& collisions) {
  std::string xml = "<link name=\"" + name + "\">";
  for (const std::string& c : collisions) xml += "<collision>" + c + "</collision>";
  return xml + "</link><joint name=\"" + name + "_joint\" type=\"fixed\"><parent link=\"base\"/>" +
         "<child link=\"" + name + "\"/></joint>";
}

/// A fresh directory for the STL files and the URDF naming them.
class RobotLinksTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char name[] = "/tmp/test_robot_links_XXXXXX";
    ASSERT_NE(::mkdtemp(name), nullptr);
    directory_ = name;
    write("wedge_mm.stl", wedgeStl());
    write("empty.stl", "solid nothing\nendsolid nothing\n");
    write("garbage.dae", "this is not a mesh\n");
  }
  void TearDown() override {
    for (const std::string& file : files_) ::unlink(file.c_str());
    ::rmdir(directory_.c_str());
  }

  void write(const std::string& file_name, const std::string& text) {
    files_.push_back(directory_ + "/" + file_name);
    std::ofstream(files_.back()) << text;
  }

  std::string fileUri(const std::string& file_name) const {
    return "file://" + directory_ + "/" + file_name;
  }

  std::string urdf() const {
    const std::string dae = "package://deformable_collision/test/ros/data/tetra_cm.dae";
    return "<robot name=\"test_gripper\"><link name=\"base\"/>" +
           linkXml("box_link", {originXml(kBoxXyz, kBoxRpy) +
                                "<geometry><box size=\"0.02 0.01 0.04\"/></geometry>"}) +
           linkXml("cylinder_link",
                   {originXml(kCylinderXyz, kCylinderRpy) +
                    "<geometry><cylinder radius=\"0.008\" length=\"0.03\"/></geometry>"}) +
           linkXml("sphere_link", {originXml(kSphereXyz, kZero) +
                                   "<geometry><sphere radius=\"0.01\"/></geometry>"}) +
           linkXml("stl_link",
                   {originXml(kStlXyz, kStlRpy) + "<geometry>" +
                    meshXml(fileUri("wedge_mm.stl"), "0.001 0.001 0.001") + "</geometry>"}) +
           linkXml("dae_link", {originXml(kDaeXyz, kDaeRpy) + "<geometry>" + meshXml(dae, "2 1 1") +
                                    "</geometry>",
                                originXml(kPadXyz, kZero) +
                                    "<geometry><box size=\"0.01 0.01 0.002\"/></geometry>"}) +
           "<link name=\"visual_only_link\"><visual><geometry><box size=\"0.01 0.01 0.01\"/>" +
           "</geometry></visual></link><joint name=\"visual_only_joint\" type=\"fixed\">" +
           "<parent link=\"base\"/><child link=\"visual_only_link\"/></joint>" +
           linkXml("missing_mesh_link",
                   {"<geometry>" + meshXml(fileUri("no_such.stl"), "1 1 1") + "</geometry>"}) +
           linkXml("bad_uri_link",
                   {"<geometry>" + meshXml("nowhere://finger.stl", "1 1 1") + "</geometry>"}) +
           linkXml("garbage_mesh_link",
                   {"<geometry>" + meshXml(fileUri("garbage.dae"), "1 1 1") + "</geometry>"}) +
           linkXml("empty_mesh_link",
                   {"<geometry>" + meshXml(fileUri("empty.stl"), "1 1 1") + "</geometry>"}) +
           "</robot>";
  }

  /// Each good link's true surfaces in its frame, one per collision element.
  static std::map<std::string, std::vector<Surface>> trueSurfaces() {
    const Eigen::Vector3d box_half(0.01, 0.005, 0.02), pad_half(0.005, 0.005, 0.001);
    const Surface box{[=](const Eigen::Vector3d& p) { return test::boxDistance(box_half, p); },
                      [=](std::mt19937& r) { return test::drawOnBox(box_half, r); }};
    const Surface pad{[=](const Eigen::Vector3d& p) { return test::boxDistance(pad_half, p); },
                      [=](std::mt19937& r) { return test::drawOnBox(pad_half, r); }};
    const Surface cylinder{
        [](const Eigen::Vector3d& p) { return test::cylinderDistance(0.008, 0.03, p); },
        [](std::mt19937& r) { return test::drawOnCylinder(0.008, 0.03, r); }};
    const Surface sphere{[](const Eigen::Vector3d& p) { return std::abs(p.norm() - 0.01); },
                         [](std::mt19937& r) { return test::drawOnSphere(0.01, r); }};
    // The COLLADA tetrahedron: 3 x 2 x 1 cm moved 1 cm along x by its node, then scaled.
    const Eigen::Isometry3d dae_node(Eigen::Translation3d(0.02, 0.0, 0.0));
    return {{"box_link", {test::placed(box, origin(kBoxXyz, kBoxRpy))}},
            {"cylinder_link", {test::placed(cylinder, origin(kCylinderXyz, kCylinderRpy))}},
            {"sphere_link", {test::placed(sphere, origin(kSphereXyz, kZero))}},
            {"stl_link", {meshSurface(tetra({0.02, 0.01, 0.03}, origin(kStlXyz, kStlRpy)))}},
            {"dae_link",
             {meshSurface(tetra({0.06, 0.02, 0.01}, origin(kDaeXyz, kDaeRpy) * dae_node)),
              test::placed(pad, origin(kPadXyz, kZero))}}};
  }

  /// The message of the exception sampling `link` throws; fails the test if none.
  std::string errorOf(const std::string& link) const {
    try {
      RobotLinks(urdf()).sampleSurface(link, {kSpacing, 100000});
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    ADD_FAILURE() << "no std::invalid_argument for " << link;
    return "";
  }

 private:
  std::string directory_;
  std::vector<std::string> files_;
};

TEST_F(RobotLinksTest, EveryPointLiesOnTheLinksTrueSurfaceInTheLinkFrame) {
  const RobotLinks robot(urdf());
  for (const auto& [link, surfaces] : trueSurfaces()) {
    const Points points = robot.sampleSurface(link, {kSpacing, 100000});
    ASSERT_FALSE(points.empty()) << link;
    double worst = 0.0;
    for (const Eigen::Vector3d& p : points) {
      double nearest = std::numeric_limits<double>::infinity();
      for (const Surface& surface : surfaces) nearest = std::min(nearest, surface.distance(p));
      worst = std::max(worst, nearest);
    }
    EXPECT_LE(worst, kOnSurfaceM) << link;
  }
}

TEST_F(RobotLinksTest, EverySurfacePointIsWithinTheSpacingOfAPoint) {
  const RobotLinks robot(urdf());
  for (const auto& [link, surfaces] : trueSurfaces()) {
    const Points points = robot.sampleSurface(link, {kSpacing, 100000});
    for (std::size_t i = 0; i < surfaces.size(); ++i) {
      const double worst = test::farthestProbe(surfaces[i], points, 5000);
      EXPECT_LE(worst, kSpacing + kOnSurfaceM) << link << ", collision " << i;
      std::printf(
          "[ MEASURED ] %s, collision %zu: %zu points in all, farthest probe %.3f of the "
          "spacing\n",
          link.c_str(), i, points.size(), worst / kSpacing);
    }
  }
}

TEST_F(RobotLinksTest, SamplesAreTheSameEachTime) {
  const RobotLinks robot(urdf());
  for (const auto& entry : trueSurfaces()) {
    EXPECT_EQ(robot.sampleSurface(entry.first, {kSpacing, 100000}),
              RobotLinks(urdf()).sampleSurface(entry.first, {kSpacing, 100000}))
        << entry.first;
  }
}

TEST_F(RobotLinksTest, EachBadLinkIsRefusedNamingItAndWhy) {
  struct Case {
    std::string link, why;
  };
  for (const Case& c : std::vector<Case>{
           {"no_such_link", "no such link in the robot description"},
           {"visual_only_link", "has no collision geometry"},
           {"missing_mesh_link", "no_such.stl': cannot be retrieved"},
           {"bad_uri_link", "mesh 'nowhere://finger.stl': cannot be retrieved"},
           {"garbage_mesh_link", "garbage.dae': assimp cannot read it"},
           {"empty_mesh_link", "empty.stl': holds no triangle"},
       }) {
    const std::string error = errorOf(c.link);
    EXPECT_NE(error.find("robot link '" + c.link + "'"), std::string::npos) << error;
    EXPECT_NE(error.find(c.why), std::string::npos) << error;
  }
}

TEST_F(RobotLinksTest, ALinkOfMorePointsThanAllowedIsRefusedNamingIt) {
  const RobotLinks robot(urdf());
  const std::size_t count = robot.sampleSurface("dae_link", {kSpacing, 100000}).size();
  EXPECT_EQ(robot.sampleSurface("dae_link", {kSpacing, count}).size(), count);
  try {
    robot.sampleSurface("dae_link", {kSpacing, count - 1});
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    const std::string error = e.what();
    EXPECT_NE(error.find("robot link 'dae_link': collision 1"), std::string::npos) << error;
    EXPECT_NE(error.find("allowed"), std::string::npos) << error;
  }
}

TEST(RobotLinks, AnUnparsableDescriptionIsRefused) {
  for (const std::string xml :
       {"", "not xml", "<robot name=\"r\"><link name=\"a\">", "<robot name=\"r\"></robot>",
        "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/></robot>"}) {
    EXPECT_THROW(RobotLinks{xml}, std::invalid_argument) << xml;
  }
}

}  // namespace
}  // namespace deformable_collision
