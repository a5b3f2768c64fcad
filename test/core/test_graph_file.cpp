// Saved pose graphs (graph_file.h): a written graph reads back equal; missing, foreign, truncated and
// corrupt files give a GraphFileError with the reason (never a crash nor a huge allocation); a loaded graph
// starts a new session in LoopClosure (anchor and tie of its first keyframe, keyframes of other runs
// always separated, keyframeAt confined to the run).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "aloam_nodelet/core/graph_file.h"
#include "aloam_nodelet/core/loop_closure.h"
#include "aloam_nodelet/core/mapping_session.h"
#include "aloam_nodelet/core/pipeline.h"
#include "test_support.h"

namespace aloam
{
namespace
{
namespace ts = test_support;

/// A scratch file removed at the end of the test.
struct TempFile
{
  std::string path;
  explicit TempFile(const std::string& name)
    : path((std::filesystem::temp_directory_path() / (name + "." + std::to_string(::getpid()))).string())
  {
  }
  ~TempFile() { std::remove(path.c_str()); }
};

std::vector<char> readBytes(const std::string& path)
{
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void writeBytes(const std::string& path, const std::vector<char>& bytes)
{
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::shared_ptr<const Cloud> randomCloud(std::mt19937& rng, int n)
{
  std::uniform_real_distribution<float> u(-30.0f, 30.0f);
  auto cloud = std::make_shared<Cloud>();
  for (int i = 0; i < n; ++i)
  {
    cloud->push_back(ts::makePoint(u(rng), u(rng), 0.1 * u(rng), 0, 0.5f * (u(rng) + 30.0f)));
  }
  return cloud;
}

Pose randomPose(std::mt19937& rng)
{
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Pose(Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng) + 2.0).normalized(),
              Eigen::Vector3d(100.0 * u(rng), 100.0 * u(rng), u(rng)));
}

/// A graph of two sessions: keyframes with clouds and descriptors (one without clouds, as dropped), odometry,
/// loop (one disabled) and anchor edges with distinct information matrices.
LoopGraph sampleGraph(int keyframes, int points)
{
  std::mt19937 rng(7);
  LoopGraph g;
  g.descriptor.rings = 4;
  g.descriptor.sectors = 8;
  g.keyframe_corner_leaf = 0.3;
  g.keyframe_surf_leaf = 0.7;
  for (int i = 0; i < keyframes; ++i)
  {
    Keyframe k;
    k.stamp = 100.0 + 0.7 * i;
    k.session = i < keyframes / 2 ? 0 : 1;
    k.pose = randomPose(rng);
    k.path = 1.1 * i;
    if (i != 1)
    {
      k.corners = randomCloud(rng, points);
      k.surfs = randomCloud(rng, 2 * points);
      k.descriptor = ScanContext::compute(*k.corners, *k.surfs, k.pose, g.descriptor);
    }
    g.keyframes.push_back(k);
  }
  for (int i = 1; i < keyframes; ++i)
  {
    PoseGraphEdge e;
    e.from = i - 1;
    e.to = i;
    e.measured = randomPose(rng);
    e.sqrt_information = sqrtInformation(0.01 * i, 0.006 * i);
    e.sqrt_information(0, 4) = 0.5 * i;  // a full matrix, not only its diagonal
    e.loop = i % 3 == 0;
    e.enabled = i != 3;
    g.edges.push_back(e);
  }
  PoseGraphEdge loop;
  loop.from = keyframes - 1;
  loop.to = 0;
  loop.measured = randomPose(rng);
  loop.loop = true;
  g.edges.push_back(loop);
  return g;
}

void expectSameCloud(const std::shared_ptr<const Cloud>& a, const std::shared_ptr<const Cloud>& b)
{
  ASSERT_EQ(a == nullptr, b == nullptr);
  if (!a)
  {
    return;
  }
  ASSERT_EQ(a->size(), b->size());
  for (std::size_t i = 0; i < a->size(); ++i)
  {
    EXPECT_EQ(a->points[i].x, b->points[i].x);
    EXPECT_EQ(a->points[i].y, b->points[i].y);
    EXPECT_EQ(a->points[i].z, b->points[i].z);
    EXPECT_EQ(a->points[i].intensity, b->points[i].intensity);
  }
}

void expectSamePose(const Pose& a, const Pose& b)
{
  EXPECT_EQ(a.t, b.t);
  EXPECT_EQ(a.q.coeffs(), b.q.coeffs());
}

TEST(GraphFileTest, RoundTripKeepsEveryKeyframeAndEdge)
{
  const LoopGraph g = sampleGraph(12, 300);
  GraphFileInfo info;
  info.sensor = "VLP16";
  info.cube_size = 40.0;
  info.corner_leaf_size = 0.35;
  info.surf_leaf_size = 0.75;
  TempFile file("aloam_graph_roundtrip");
  writeGraphFile(file.path, g, info);
  EXPECT_FALSE(std::filesystem::exists(file.path + ".tmp"));
  const GraphFile read = readGraphFile(file.path);

  EXPECT_EQ(read.version, kGraphFormatVersion);
  EXPECT_EQ(read.info.sensor, "VLP16");
  EXPECT_EQ(read.info.cube_size, 40.0);
  EXPECT_EQ(read.info.corner_leaf_size, 0.35);
  EXPECT_EQ(read.info.surf_leaf_size, 0.75);
  EXPECT_EQ(read.graph.keyframe_corner_leaf, 0.3);
  EXPECT_EQ(read.graph.keyframe_surf_leaf, 0.7);
  EXPECT_EQ(read.graph.descriptor.rings, 4);
  EXPECT_EQ(read.graph.descriptor.sectors, 8);
  EXPECT_EQ(read.graph.descriptor.max_range, g.descriptor.max_range);
  EXPECT_EQ(read.graph.descriptor.lift, g.descriptor.lift);
  ASSERT_EQ(read.graph.keyframes.size(), g.keyframes.size());
  for (std::size_t i = 0; i < g.keyframes.size(); ++i)
  {
    SCOPED_TRACE("keyframe " + std::to_string(i));
    const Keyframe &a = g.keyframes[i], &b = read.graph.keyframes[i];
    EXPECT_EQ(a.stamp, b.stamp);
    EXPECT_EQ(a.session, b.session);
    EXPECT_EQ(a.path, b.path);
    expectSamePose(a.pose, b.pose);
    expectSameCloud(a.corners, b.corners);
    expectSameCloud(a.surfs, b.surfs);
    ASSERT_EQ(a.descriptor.cells().rows(), b.descriptor.cells().rows());
    ASSERT_EQ(a.descriptor.cells().cols(), b.descriptor.cells().cols());
    EXPECT_EQ(a.descriptor.cells(), b.descriptor.cells());
    EXPECT_EQ(a.descriptor.ringKey(), b.descriptor.ringKey());
    if (!a.descriptor.empty())
    {
      const ScanContextMatch m = b.descriptor.match(a.descriptor);
      EXPECT_NEAR(m.distance, 0.0, 1e-6);  // the descriptor read back is the same place
    }
  }
  EXPECT_TRUE(read.graph.keyframes[1].descriptor.empty());
  ASSERT_EQ(read.graph.edges.size(), g.edges.size());
  for (std::size_t i = 0; i < g.edges.size(); ++i)
  {
    SCOPED_TRACE("edge " + std::to_string(i));
    const PoseGraphEdge &a = g.edges[i], &b = read.graph.edges[i];
    EXPECT_EQ(a.from, b.from);
    EXPECT_EQ(a.to, b.to);
    expectSamePose(a.measured, b.measured);
    EXPECT_EQ(a.sqrt_information, b.sqrt_information);
    EXPECT_EQ(a.loop, b.loop);
    EXPECT_EQ(a.enabled, b.enabled);
  }
}

/// Reading `bytes` as a graph must throw GraphFileError (no other exception, no crash); returns its text.
std::string readError(const std::string& path, const std::vector<char>& bytes)
{
  writeBytes(path, bytes);
  try
  {
    readGraphFile(path);
  }
  catch (const GraphFileError& e)
  {
    return e.what();
  }
  ADD_FAILURE() << "a file of " << bytes.size() << " bytes was read without an error";
  return "";
}

bool contains(const std::string& text, const std::string& part)
{
  return text.find(part) != std::string::npos;
}

TEST(GraphFileTest, MissingForeignTruncatedAndCorruptFilesGiveTheReason)
{
  TempFile good("aloam_graph_good"), bad("aloam_graph_bad");
  writeGraphFile(good.path, sampleGraph(4, 6), GraphFileInfo());
  const std::vector<char> bytes = readBytes(good.path);
  ASSERT_GT(bytes.size(), 200u);

  try
  {
    readGraphFile(good.path + ".missing");
    ADD_FAILURE() << "a missing file was read";
  }
  catch (const GraphFileError& e)
  {
    EXPECT_TRUE(contains(e.what(), "cannot read graph")) << e.what();
  }
  EXPECT_TRUE(contains(readError(bad.path, {}), "too short")) << readError(bad.path, {});
  const std::string pcd = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\n";
  EXPECT_TRUE(contains(readError(bad.path, std::vector<char>(pcd.begin(), pcd.end())), "wrong magic"));

  // A newer version.
  std::vector<char> newer = bytes;
  newer[8] = 9;
  EXPECT_TRUE(contains(readError(bad.path, newer), "format version 9")) << readError(bad.path, newer);

  // Cut anywhere: an error, never a crash.
  for (std::size_t size = 0; size < bytes.size(); ++size)
  {
    const std::string e = readError(bad.path, std::vector<char>(bytes.begin(), bytes.begin() + size));
    EXPECT_TRUE(contains(e, "truncated") || contains(e, "too short") || contains(e, "corrupt")) << size << ": " << e;
  }
  // Every single byte changed: an error (the checksum covers what the field checks do not).
  std::size_t checksum_errors = 0;
  for (std::size_t i = 0; i < bytes.size(); ++i)
  {
    std::vector<char> flipped = bytes;
    flipped[i] = static_cast<char>(flipped[i] ^ 0x5A);
    const std::string e = readError(bad.path, flipped);
    EXPECT_FALSE(e.empty()) << "byte " << i;
    checksum_errors += contains(e, "checksum");
  }
  EXPECT_GT(checksum_errors, bytes.size() / 2);  // most bytes are clouds, caught by the checksum alone
  // An appended byte.
  std::vector<char> longer = bytes;
  longer.push_back('x');
  EXPECT_TRUE(contains(readError(bad.path, longer), "corrupt")) << readError(bad.path, longer);

  // A huge keyframe count is refused before anything is allocated. Its offset: magic 8, version 4, sensor
  // name 4 + 0, five sizes 40, descriptor 4 + 4 + 8 + 8.
  const std::size_t count_at = 8 + 4 + 4 + 40 + 24;
  std::vector<char> huge = bytes;
  for (int i = 0; i < 8; ++i)
  {
    huge[count_at + i] = static_cast<char>(i == 7 ? 0x10 : 0xFF);
  }
  const std::string e = readError(bad.path, huge);
  EXPECT_TRUE(contains(e, "cannot fit")) << e;
}

TEST(GraphFileTest, WritingToAnUnwritablePlaceFailsAndKeepsTheOldFile)
{
  TempFile file("aloam_graph_keep");
  const LoopGraph g = sampleGraph(3, 5);
  writeGraphFile(file.path, g, GraphFileInfo());
  EXPECT_THROW(writeGraphFile("/nonexistent-dir/graph.bin", g, GraphFileInfo()), GraphFileError);
  EXPECT_EQ(readGraphFile(file.path).graph.keyframes.size(), 3u);
}

TEST(GraphFileTest, SettingsWarningsNameWhatDiffers)
{
  GraphFileInfo saved, now;
  EXPECT_TRUE(graphSettingsWarnings(saved, now).empty());
  saved.sensor = "HDL64";
  now.sensor = "VLP16";
  now.surf_leaf_size = 0.6;
  const std::vector<std::string> w = graphSettingsWarnings(saved, now);
  ASSERT_EQ(w.size(), 2u);
  EXPECT_TRUE(contains(w[0], "HDL64")) << w[0];
  EXPECT_TRUE(contains(w[1], "0.60")) << w[1];
}

// One-point keyframes (as KeyframesFollowDistanceAngleAndTheCloudBound): enough for the session rules, which
// need no registration to succeed.
TEST(LoopClosureImportTest, ALoadedGraphStartsANewSession)
{
  const Cloud one = ts::cloudOf({ ts::makePoint(1.0, 2.0, 3.0) }), none;
  LoopClosure first;
  for (int i = 0; i < 4; ++i)
  {
    first.addFrame(10.0 + i, Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(2.0 * i, 0.0, 0.0)), one, none);
  }
  LoopGraph saved = first.exportGraph();
  ASSERT_EQ(saved.keyframes.size(), 4u);
  ASSERT_EQ(saved.edges.size(), 3u);

  // Inconsistent graphs are refused and change nothing.
  LoopClosure second;
  second.addFrame(0.0, Pose(), one, none);
  LoopGraph broken = saved;
  broken.edges[1].to = 9;
  EXPECT_THROW(second.importGraph(broken), std::invalid_argument);
  broken = saved;
  broken.keyframes[2].pose.t.x() = std::nan("");
  EXPECT_THROW(second.importGraph(broken), std::invalid_argument);
  EXPECT_EQ(second.stats().keyframes, 1u);
  EXPECT_EQ(second.stats().keyframes_loaded, 0u);

  EXPECT_TRUE(second.importGraph(saved).empty());
  LoopClosureStats s = second.stats();
  EXPECT_EQ(s.keyframes, 4u);
  EXPECT_EQ(s.keyframes_loaded, 4u);
  EXPECT_EQ(s.tie, SessionTie::kPending);
  EXPECT_EQ(second.mapSweeps().size(), 4u);
  EXPECT_EQ(second.keyframeAt(12.0), 4u);  // no keyframe of this run yet

  // The run's first keyframe, with the stamps of the first run (a replay): near loaded keyframe 1.
  const LoopUpdate u =
      second.addFrame(10.0, Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(2.3, 0.5, 0.0)), one, none);
  ASSERT_TRUE(u.keyframe);
  ASSERT_EQ(u.tried.size(), 1u);
  EXPECT_EQ(u.tried[0].source, LoopSource::kSessionStart);
  EXPECT_EQ(u.tried[0].from, 1u);
  EXPECT_EQ(u.tried[0].to, 4u);
  EXPECT_FALSE(u.tried[0].accepted);  // one point is no submap to register against
  EXPECT_FALSE(u.tried[0].reason.empty());
  s = second.stats();
  EXPECT_EQ(s.tie, SessionTie::kNotTied);
  EXPECT_EQ(s.tie_reason, u.tried[0].reason);
  EXPECT_EQ(second.keyframes().back().session, 1);
  EXPECT_EQ(second.keyframes().back().path, 0.0);
  // The anchor: a loose, non-loop edge from the nearest loaded keyframe, measured where the run put it.
  const PoseGraphEdge& anchor = second.graph().edges().back();
  EXPECT_EQ(anchor.from, 1u);
  EXPECT_EQ(anchor.to, 4u);
  EXPECT_FALSE(anchor.loop);
  EXPECT_NEAR(anchor.measured.t.x(), 0.3, 1e-12);
  EXPECT_DOUBLE_EQ(anchor.sqrt_information(0, 0), 1.0 / LoopClosureConfig().session_anchor_sigma_translation);
  EXPECT_EQ(second.keyframeAt(100.0), 4u);
  EXPECT_EQ(second.keyframeAt(0.0), 4u);

  // The next keyframes of the run: odometry edges from its own, loop candidates among the loaded ones only
  // (every loaded keyframe is separated from this run, whatever the stamps).
  const LoopUpdate next =
      second.addFrame(11.0, Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(4.3, 0.5, 0.0)), one, none);
  ASSERT_TRUE(next.keyframe);
  EXPECT_EQ(second.graph().edges().back().from, 4u);
  EXPECT_EQ(second.graph().edges().back().to, 5u);
  for (const LoopRecord& r : next.tried)
  {
    EXPECT_LT(r.from, 4u);
  }
  EXPECT_FALSE(next.tried.empty());  // nearby loaded keyframes are tried at once, 1 s later
  EXPECT_EQ(second.keyframeAt(11.5), 5u);

  // Exported again, the graph holds both runs.
  const LoopGraph both = second.exportGraph();
  EXPECT_EQ(both.keyframes.size(), 6u);
  EXPECT_EQ(both.edges.size(), 3u + 1u + 1u);
  EXPECT_EQ(both.keyframes[3].session, 0);
  EXPECT_EQ(both.keyframes[5].session, 1);
  // A reset forgets the loaded graph too.
  second.reset();
  EXPECT_EQ(second.stats().keyframes_loaded, 0u);
  EXPECT_EQ(second.stats().tie, SessionTie::kNone);
}

TEST(LoopClosureImportTest, DescriptorsOfOtherSettingsAreRemade)
{
  const LoopGraph g = sampleGraph(3, 200);
  LoopClosure loops;  // default descriptor: 20 x 60
  const std::vector<std::string> warnings = loops.importGraph(g);
  ASSERT_EQ(warnings.size(), 2u);  // the descriptors, and the keyframe leaves
  for (const Keyframe& k : loops.keyframes())
  {
    if (k.corners)
    {
      EXPECT_EQ(k.descriptor.cells().rows(), ScanContextConfig().rings);
      EXPECT_EQ(k.descriptor.cells().cols(), ScanContextConfig().sectors);
    }
  }
}

TEST(LoopClosureImportTest, SessionAndPipelineNeedLoopClosureOn)
{
  const LoopGraph g = sampleGraph(3, 50);
  MappingSession off;
  EXPECT_THROW(off.loadGraph(g, Pose()), std::logic_error);
  EXPECT_TRUE(off.exportGraph().keyframes.empty());
  Pipeline pipeline;
  EXPECT_THROW(pipeline.loadGraph(g, Pose()), std::logic_error);

  MappingSessionConfig config;
  config.loop_closure = true;
  MappingSession on(config);
  on.loadGraph(g, Pose());
  const MappingSessionStats stats = on.stats();
  EXPECT_EQ(stats.loops.keyframes_loaded, 3u);
  // The map is the loaded keyframes' clouds (two have them).
  std::size_t points = 0;
  on.withMap([&](const CubeMap& map) { points = map.cornerCount() + map.surfCount(); });
  EXPECT_GT(points, 0u);
  EXPECT_EQ(on.exportGraph().keyframes.size(), 3u);
}

}  // namespace
}  // namespace aloam
