#include "deformable_collision/ros/mesh_file.h"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <resource_retriever/retriever.h>

#include <stdexcept>

namespace deformable_collision {
namespace {

std::invalid_argument meshError(const std::string& uri, const std::string& what) {
  return std::invalid_argument("mesh '" + uri + "': " + what);
}

/// The URI's extension, assimp's hint of the format when the content does not tell it.
std::string extensionOf(const std::string& uri) {
  const std::size_t dot = uri.find_last_of('.');
  const std::size_t slash = uri.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  return uri.substr(dot + 1);
}

/// Appends the triangles of `node`'s meshes and of its children's, placed by `parent` times
/// the node's own transform. Points and lines (faces of fewer corners) have no surface.
void addNode(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent,
             TriangleMesh& out) {
  const aiMatrix4x4 transform = parent * node.mTransformation;
  for (unsigned int m = 0; m < node.mNumMeshes; ++m) {
    const aiMesh& mesh = *scene.mMeshes[node.mMeshes[m]];
    const auto first = static_cast<std::uint32_t>(out.vertices.size());
    for (unsigned int v = 0; v < mesh.mNumVertices; ++v) {
      const aiVector3D p = transform * mesh.mVertices[v];
      out.vertices.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned int f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3) continue;
      out.triangles.push_back(
          {first + face.mIndices[0], first + face.mIndices[1], first + face.mIndices[2]});
    }
  }
  for (unsigned int c = 0; c < node.mNumChildren; ++c) {
    addNode(scene, *node.mChildren[c], transform, out);
  }
}

}  // namespace

TriangleMesh readMeshFile(const std::string& uri, const Eigen::Vector3d& scale) {
  resource_retriever::MemoryResource resource;
  try {
    resource = resource_retriever::Retriever().get(uri);
  } catch (const resource_retriever::Exception& e) {
    throw meshError(uri, std::string("cannot be retrieved: ") + e.what());
  }
  Assimp::Importer importer;
  importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, true);
  const aiScene* scene = importer.ReadFileFromMemory(
      resource.data.get(), resource.size, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices,
      extensionOf(uri).c_str());
  if (scene == nullptr || scene->mRootNode == nullptr) {
    throw meshError(uri, std::string("assimp cannot read it: ") + importer.GetErrorString());
  }
  TriangleMesh mesh;
  addNode(*scene, *scene->mRootNode, aiMatrix4x4(), mesh);
  if (mesh.triangles.empty()) throw meshError(uri, "holds no triangle");
  for (Eigen::Vector3d& v : mesh.vertices) v = v.cwiseProduct(scale);
  return mesh;
}

}  // namespace deformable_collision
