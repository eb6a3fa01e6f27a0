// Internal to the ROS layer: reading one dictionary of the node's parameters.
#pragma once

#include <xmlrpcpp/XmlRpcValue.h>

#include <Eigen/Core>
#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_collision {
namespace detail {

inline const char* typeName(XmlRpc::XmlRpcValue::Type type) {
  switch (type) {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return "a boolean";
    case XmlRpc::XmlRpcValue::TypeInt:
      return "an integer";
    case XmlRpc::XmlRpcValue::TypeDouble:
      return "a number";
    case XmlRpc::XmlRpcValue::TypeString:
      return "a string";
    case XmlRpc::XmlRpcValue::TypeArray:
      return "a list";
    case XmlRpc::XmlRpcValue::TypeStruct:
      return "a dictionary";
    default:
      return "an unsupported value";
  }
}

/// Reads the members of one parameter dictionary, remembering which it used, so that
/// finish() can name the keys nobody asked for. `path` prefixes every message.
class ParamReader {
 public:
  ParamReader(XmlRpc::XmlRpcValue params, std::string path)
      : params_(std::move(params)), path_(std::move(path)) {
    if (params_.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
      fail(path_.empty() ? "parameters" : path_,
           std::string("must be a dictionary, got ") + typeName(params_.getType()));
    }
  }

  [[noreturn]] static void fail(const std::string& name, const std::string& problem) {
    throw std::invalid_argument("parameter " + name + " " + problem);
  }

  std::string name(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

  const XmlRpc::XmlRpcValue* find(const std::string& key) {
    used_.insert(key);
    if (!params_.hasMember(key)) return nullptr;
    return &params_[key];
  }

  double number(const std::string& key, double fallback, double low, double high,
                bool low_open = false) {
    const XmlRpc::XmlRpcValue* value = find(key);
    if (value == nullptr) return fallback;
    const double x = toDouble(*value, name(key));
    const bool above = low_open ? x > low : x >= low;
    if (!(std::isfinite(x) && above && x <= high)) {
      std::ostringstream out;
      out << "= " << x << " must be in " << (low_open ? "(" : "[") << low << ", " << high << "]";
      fail(name(key), out.str());
    }
    return x;
  }

  long integer(const std::string& key, long fallback, long low, long high) {
    const XmlRpc::XmlRpcValue* value = find(key);
    if (value == nullptr) return fallback;
    if (value->getType() != XmlRpc::XmlRpcValue::TypeInt) {
      fail(name(key), std::string("must be an integer, got ") + typeName(value->getType()));
    }
    const long x = static_cast<int>(*value);
    if (x < low || x > high) {
      fail(name(key), "= " + std::to_string(x) + " must be in [" + std::to_string(low) + ", " +
                          std::to_string(high) + "]");
    }
    return x;
  }

  bool flag(const std::string& key, bool fallback) {
    const XmlRpc::XmlRpcValue* value = find(key);
    if (value == nullptr) return fallback;
    if (value->getType() != XmlRpc::XmlRpcValue::TypeBoolean) {
      fail(name(key), std::string("must be true or false, got ") + typeName(value->getType()));
    }
    return static_cast<bool>(*value);
  }

  std::string text(const std::string& key, const std::string& fallback) {
    const XmlRpc::XmlRpcValue* value = find(key);
    if (value == nullptr) return fallback;
    if (value->getType() != XmlRpc::XmlRpcValue::TypeString) {
      fail(name(key), std::string("must be a string, got ") + typeName(value->getType()));
    }
    return static_cast<std::string>(*value);
  }

  std::string requiredText(const std::string& key) {
    if (!params_.hasMember(key)) fail(name(key), "is missing");
    const std::string value = text(key, "");
    if (value.empty()) fail(name(key), "is empty");
    return value;
  }

  Eigen::Vector3d vector3(const std::string& key, const Eigen::Vector3d& fallback) {
    const XmlRpc::XmlRpcValue* value = find(key);
    if (value == nullptr) return fallback;
    if (value->getType() != XmlRpc::XmlRpcValue::TypeArray || value->size() != 3) {
      fail(name(key), "must be a list of 3 numbers [x, y, z]");
    }
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) {
      v[i] = toDouble((*value)[i], name(key) + "[" + std::to_string(i) + "]");
      if (!std::isfinite(v[i])) fail(name(key), "must be finite");
    }
    return v;
  }

  /// The key to read a renamed parameter from: `key`, or `old_key` (the name before units
  /// were part of it) with one warning in `warnings`, so that older configs still load.
  std::string renamed(const std::string& key, const std::string& old_key,
                      std::vector<std::string>& warnings) {
    used_.insert(old_key);
    if (!params_.hasMember(old_key)) return key;
    if (params_.hasMember(key)) {
      fail(name(old_key),
           "is the deprecated name of " + name(key) + ", which is set too: keep only " + name(key));
    }
    warnings.push_back("parameter " + name(old_key) + " is deprecated: rename it " + name(key));
    return old_key;
  }

  /// Throws for the first key that was never asked for.
  void finish() {
    for (auto it = params_.begin(); it != params_.end(); ++it) {
      if (used_.count(it->first) == 0) fail(name(it->first), "is not a known parameter");
    }
  }

 private:
  static double toDouble(const XmlRpc::XmlRpcValue& value, const std::string& name) {
    if (value.getType() == XmlRpc::XmlRpcValue::TypeInt) return static_cast<int>(value);
    if (value.getType() == XmlRpc::XmlRpcValue::TypeDouble) return static_cast<double>(value);
    fail(name, std::string("must be a number, got ") + typeName(value.getType()));
  }

  XmlRpc::XmlRpcValue params_;
  std::string path_;
  std::set<std::string> used_;
};

}  // namespace detail
}  // namespace deformable_collision
