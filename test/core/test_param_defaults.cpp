// Code defaults are the truth (issue 13): every cfg/*.cfg default equals the code default of the same
// parameter, and every value of a sensor YAML (config/*.yaml) that differs from its code default carries
// a comment on its line, or in the comment lines directly above it, that names the "code default" and
// says why the sensor differs, e.g. `deskew: true  # code default false: this driver fills per-point time`.
//
// Code defaults come from default-constructed config structs where a parameter maps onto one (the
// nodelets copy cfg and private parameters into these fields under the same names), otherwise from the
// literal fallback of the pnh.param / boundedParam call in the nodelet or a nodelet header it includes
// (or the member it defaults to), and
// for the few parameters that only the .cfg declares (scan_registration's sensor and beams) from there.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/laser_mapping.h"
#include "aloam_nodelet/core/mapping_session.h"
#include "aloam_nodelet/core/laser_odometry.h"
#include "aloam_nodelet/core/scan_registration.h"
#include "aloam_nodelet/core/stamp_check.h"
#include "aloam_nodelet/ros/pointcloud2_reader.h"

namespace
{
namespace fs = std::filesystem;
using Defaults = std::map<std::string, std::string>;  // parameter -> value as written (canonical below)

const fs::path kRoot = ALOAM_SOURCE_DIR;
const char* const kNodes[] = { "scan_registration", "laser_odometry", "laser_mapping" };

std::string readFile(const fs::path& path)
{
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string str(bool b)
{
  return b ? "true" : "false";
}
template <typename T>
std::string str(T v)
{
  std::ostringstream s;
  s.precision(15);
  s << v;
  return s.str();
}

std::string trim(const std::string& s)
{
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t\r");
  return b == std::string::npos ? "" : s.substr(b, e - b + 1);
}

// Values compare as numbers when both are numbers, as booleans (True/true) or as unquoted strings.
std::optional<double> number(const std::string& v)
{
  std::string s;
  for (char c : v)
  {
    if (c != '\'')  // C++ digit separators
    {
      s += c;
    }
  }
  char* end = nullptr;
  const double d = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size())
  {
    return std::nullopt;
  }
  return d;
}

std::string canonical(std::string v)
{
  v = trim(v);
  if (v.size() >= 2 && (v.front() == '"' || v.front() == '\'') && v.back() == v.front())
  {
    v = v.substr(1, v.size() - 2);
  }
  if (v == "True" || v == "true")
  {
    return "true";
  }
  if (v == "False" || v == "false")
  {
    return "false";
  }
  return v;
}

bool sameValue(const std::string& a, const std::string& b)
{
  const auto x = number(canonical(a)), y = number(canonical(b));
  if (x && y)
  {
    return std::abs(*x - *y) <= 1e-9 * std::max(1.0, std::abs(*x));
  }
  return canonical(a) == canonical(b);
}

// The parameters that map onto config struct fields, with the default-constructed values.
std::map<std::string, Defaults> structDefaults()
{
  const aloam::ScanRegistrationConfig r;
  const aloam::LaserOdometryConfig o;
  const aloam::LaserMappingConfig m;
  const aloam::MappingSessionConfig session;
  const aloam::LoopClosureConfig loop;
  const aloam::StampCheckConfig s;
  const aloam::ros_io::ReaderOptions reader;
  const Defaults stamps = { { "scan_period", str(s.scan_period) },
                            { "max_gap_sweeps", str(s.max_gap_sweeps) },
                            { "jump_back_tolerance", str(s.jump_back_tolerance) } };
  std::map<std::string, Defaults> d;
  d["scan_registration"] = stamps;
  d["scan_registration"].insert({
      { "scan_period", str(r.scan_period) },
      { "minimum_range", str(r.minimum_range) },
      { "maximum_range", str(r.maximum_range) },
      { "less_flat_leaf_size", str(r.less_flat_leaf_size) },
      { "curvature_threshold", str(r.curvature_threshold) },
      { "reject_occluded", str(r.reject_occluded) },
      { "occlusion_continuity", str(r.occlusion_continuity) },
      { "occlusion_straight_tolerance", str(r.occlusion_straight_tolerance) },
      { "curvature_across_ring", str(r.curvature_across_ring) },
      { "threads", str(r.threads) },
      { "max_points", str(reader.max_points) },
  });
  d["laser_odometry"] = stamps;
  d["laser_odometry"].insert({
      { "max_iterations", str(o.max_iterations) },
      { "outer_iterations", str(o.outer_iterations) },
      { "distance_sq_threshold", str(o.distance_sq_threshold) },
      { "nearby_scan", str(o.nearby_scan) },
      { "deskew", str(o.deskew) },
      { "degeneracy_remap", str(o.degeneracy_remap) },
      { "soft_remap", str(o.soft_remap) },
      { "time_scaling", str(o.time_scaling) },
      { "nearby_elevation_deg", str(o.nearby_elevation_deg) },
      { "motion_hypotheses", str(o.motion_hypotheses) },
      { "hypothesis_min_inlier_share", str(o.hypothesis_min_inlier_share) },
      { "hypothesis_yaw_deg", str(o.hypothesis_yaw_deg) },
      { "hypothesis_translation", str(o.hypothesis_translation) },
      { "hypothesis_outer_iterations", str(o.hypothesis_outer_iterations) },
      { "hypothesis_search_scale", str(o.hypothesis_search_scale) },
      { "hypothesis_min_gain", str(o.hypothesis_min_gain) },
      { "constant_velocity", str(o.constant_velocity) },
      { "threads", str(o.threads) },
  });
  d["laser_mapping"] = stamps;
  d["laser_mapping"].insert({
      { "cube_size", str(m.cube_size) },
      { "corner_leaf_size", str(m.corner_leaf_size) },
      { "surf_leaf_size", str(m.surf_leaf_size) },
      { "leaf_min_scale", str(m.leaf_min_scale) },
      { "leaf_reference_range", str(m.leaf_reference_range) },
      { "max_iterations", str(m.max_iterations) },
      { "outer_iterations", str(m.outer_iterations) },
      { "plane_neighbours", str(m.plane_neighbours) },
      { "degeneracy_remap", str(m.degeneracy_remap) },
      { "soft_remap", str(m.soft_remap) },
      { "sweep_span", str(m.sweep_span) },
      { "span_motion_change_deg", str(m.span_motion_change_deg) },
      { "span_motion_change_m", str(m.span_motion_change_m) },
      { "span_min_constraint", str(m.span_min_constraint) },
      { "span_start_weight", str(m.span_start_weight) },
      { "deskew_first_late", str(m.deskew_first_late) },
      { "eviction_radius", str(m.eviction_radius) },
      { "threads", str(m.threads) },
      { "loop_closure", str(session.loop_closure) },
      { "keyframe_distance", str(loop.keyframe_distance) },
      { "min_loop_separation", str(loop.min_loop_separation_time) },
      { "loop_search_radius", str(loop.search_radius) },
      { "loop_min_inlier_share", str(loop.min_inlier_share) },
      { "loop_max_mean_residual", str(loop.max_mean_residual) },
      { "loop_max_weak_directions", str(loop.max_weak_directions) },
      { "loop_max_weak_rotation", str(loop.max_weak_rotation) },
      { "loop_max_descriptor_distance", str(loop.max_descriptor_distance) },
  });
  return d;
}

bool isLiteral(const std::string& v)
{
  return (v.size() >= 2 && v.front() == '"' && v.back() == '"') || v == "true" || v == "false" || number(v).has_value();
}

// The literal fallbacks of a nodelet's parameter reads: pnh.param("name", var, FALLBACK) and
// boundedParam(pnh, logger, "name", FALLBACK, lo, hi); a FALLBACK naming a member (`x_`) resolves to
// the member's initializer. Other fallbacks (config fields, expressions) are left to structDefaults().
Defaults nodeletLiterals(const fs::path& source)
{
  const std::string text = readFile(source);
  Defaults d;
  auto resolve = [&](const std::string& name, std::string fallback)
  {
    fallback = trim(fallback);
    if (!isLiteral(fallback) && std::regex_match(fallback, std::regex(R"(\w+_)")))
    {
      std::smatch m;
      if (std::regex_search(text, m, std::regex("\\b" + fallback + R"(\s*=\s*([^;,]+)[;,])")))
      {
        fallback = trim(m[1].str());
      }
    }
    if (isLiteral(fallback))
    {
      d.emplace(name, fallback);
    }
  };
  const std::regex param(R"re(\.param(?:<[^>]*>)?\(\s*"(\w+)"\s*,\s*[\w.]+\s*,\s*([^)]+?)\s*\))re");
  const std::regex bounded(R"re(boundedParam\(\s*pnh\s*,\s*[\w()]+\s*,\s*"(\w+)"\s*,\s*([^,]+?)\s*,)re");
  for (const std::regex* re : { &param, &bounded })
  {
    for (auto it = std::sregex_iterator(text.begin(), text.end(), *re); it != std::sregex_iterator(); ++it)
    {
      resolve((*it)[1].str(), (*it)[2].str());
    }
  }
  return d;
}

struct CfgEntry
{
  std::string name, value;
  int line;
};

// gen.add("name", type, level, "description", default[, min, max][, edit_method=...]).
std::vector<CfgEntry> cfgDefaults(const fs::path& cfg)
{
  std::vector<CfgEntry> out;
  std::ifstream in(cfg);
  std::string line;
  const std::regex add(
      R"re(^\s*gen\.add\(\s*"(\w+)"\s*,\s*\w+\s*,\s*\w+\s*,\s*"(?:[^"\\]|\\.)*"\s*,\s*("[^"]*"|[^,)\s]+))re");
  for (int n = 1; std::getline(in, line); ++n)
  {
    std::smatch m;
    if (std::regex_search(line, m, add))
    {
      out.push_back({ m[1].str(), m[2].str(), n });
    }
  }
  return out;
}

const std::map<std::string, std::string> kCfgNode = { { "ScanRegistration.cfg", "scan_registration" },
                                                      { "LaserOdometry.cfg", "laser_odometry" },
                                                      { "LaserMapping.cfg", "laser_mapping" } };

// Every code default, per node: struct fields first (the truth), then the nodelets' literal fallbacks,
// then parameters that only a .cfg declares.
std::map<std::string, Defaults> codeDefaults(bool with_cfg_only)
{
  std::map<std::string, Defaults> d = structDefaults();
  for (const char* node : kNodes)
  {
    // The nodelet's source and the nodelet headers it includes (some read parameters of their own).
    const fs::path source = kRoot / "src/nodelets" / (std::string(node) + "_nodelet.cpp");
    std::vector<fs::path> files = { source };
    const std::string text = readFile(source);
    const std::regex include(R"re(#include\s+"(\w+\.h)")re");
    for (auto it = std::sregex_iterator(text.begin(), text.end(), include); it != std::sregex_iterator(); ++it)
    {
      if (fs::exists(kRoot / "src/nodelets" / (*it)[1].str()))
      {
        files.push_back(kRoot / "src/nodelets" / (*it)[1].str());
      }
    }
    for (const fs::path& file : files)
    {
      for (const auto& [name, value] : nodeletLiterals(file))
      {
        d[node].emplace(name, value);
      }
    }
  }
  if (with_cfg_only)
  {
    for (const auto& [file, node] : kCfgNode)
    {
      for (const CfgEntry& e : cfgDefaults(kRoot / "cfg" / file))
      {
        d[node].emplace(e.name, e.value);
      }
    }
  }
  return d;
}

TEST(ParamDefaults, CodeDefaultsAreFound)
{
  // The extraction itself must work, or the checks below would pass vacuously.
  const auto d = codeDefaults(false);
  EXPECT_EQ(d.at("laser_odometry").at("world_frame"), "\"camera_init\"");
  EXPECT_EQ(d.at("laser_mapping").count("map_publish_period"), 1u);
  EXPECT_EQ(d.at("laser_mapping").count("publish_tf"), 1u);
  EXPECT_EQ(d.at("scan_registration").count("min_elevation_deg"), 1u);
  EXPECT_GT(cfgDefaults(kRoot / "cfg/LaserOdometry.cfg").size(), 10u);
}

TEST(ParamDefaults, CfgDefaultsEqualCodeDefaults)
{
  const auto code = codeDefaults(false);
  int checked = 0;
  for (const auto& [file, node] : kCfgNode)
  {
    for (const CfgEntry& e : cfgDefaults(kRoot / "cfg" / file))
    {
      const auto it = code.at(node).find(e.name);
      if (it == code.at(node).end())
      {
        continue;  // declared by the .cfg only: the .cfg is its code default
      }
      ++checked;
      EXPECT_TRUE(sameValue(e.value, it->second))
          << "cfg/" << file << ":" << e.line << ": " << e.name << " defaults to " << e.value
          << " but the code default (" << node << ") is " << it->second;
    }
  }
  EXPECT_GE(checked, 30);
}

TEST(ParamDefaults, YamlValuesOffTheCodeDefaultSayWhy)
{
  const auto code = codeDefaults(true);
  int yamls = 0, values = 0;
  for (const auto& entry : fs::directory_iterator(kRoot / "config"))
  {
    const fs::path path = entry.path();
    std::ifstream in(path);
    std::string line, node;
    bool ours = false;     // sensor YAMLs only (crop_box.yaml holds pcl_ros's parameters)
    std::string comments;  // the comment lines directly above the current line
    for (int n = 1; std::getline(in, line); ++n)
    {
      const std::string t = trim(line);
      if (t.empty())
      {
        comments.clear();
        continue;
      }
      if (t.front() == '#')
      {
        comments += t + "\n";
        continue;
      }
      const auto colon = t.find(':');
      const bool top = line.front() != ' ';
      if (colon == std::string::npos)
      {
        comments.clear();
        continue;
      }
      const std::string key = t.substr(0, colon);
      std::string rest = t.substr(colon + 1);
      std::string comment;
      const auto hash = rest.find(" #");
      if (hash != std::string::npos)
      {
        comment = rest.substr(hash);
        rest = rest.substr(0, hash);
      }
      const std::string value = trim(rest);
      if (top)
      {
        node = key;
        ours = code.count(node) > 0;
      }
      else if (ours)
      {
        ++values;
        const Defaults& d = code.at(node);
        const auto it = d.find(key);
        const std::string where =
            "config/" + path.filename().string() + ":" + std::to_string(n) + ": " + node + "/" + key;
        if (it == d.end())
        {
          ADD_FAILURE() << where << " = " << value << ": no such parameter in the code (misspelt?)";
        }
        else if (key != "sensor" && !sameValue(value, it->second))
        {
          // `sensor` is what each YAML is for (its header comment says which); every other difference
          // names the code default and says why.
          EXPECT_TRUE((comment + comments).find("code default") != std::string::npos)
              << where << " = " << value << " but the code default is " << it->second
              << ": add a comment (on the line or just above) naming the code default and saying why";
        }
      }
      comments.clear();
    }
    yamls += ours ? 1 : 0;
  }
  EXPECT_GE(yamls, 7);
  EXPECT_GT(values, 100);
}

}  // namespace
