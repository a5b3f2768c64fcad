#include "aloam_nodelet/eval/trajectory_io.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace aloam
{
namespace eval
{
namespace
{
// Splits a line into whitespace-separated numbers. Returns false if any token is not a complete,
// finite number.
bool parseNumbers(const std::string& line, std::vector<double>& numbers)
{
  numbers.clear();
  std::istringstream stream(line);
  std::string token;
  while (stream >> token)
  {
    char* end = nullptr;
    const double value = std::strtod(token.c_str(), &end);
    if (end != token.c_str() + token.size() || !std::isfinite(value))
    {
      return false;
    }
    numbers.push_back(value);
  }
  return true;
}

bool isBlank(const std::string& line)
{
  return line.find_first_not_of(" \t\r\n") == std::string::npos;
}

std::string location(const std::string& path, std::size_t line_number)
{
  return path + ":" + std::to_string(line_number);
}

// Row-major 3x4 [R|t] -> 4x4 transform.
Eigen::Isometry3d poseFromRowMajor(const std::vector<double>& v)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r)
  {
    for (int c = 0; c < 4; ++c)
    {
      pose.matrix()(r, c) = v[static_cast<std::size_t>(r * 4 + c)];
    }
  }
  return pose;
}

// Parses the 12 pose numbers of one line or throws with the file position.
Eigen::Isometry3d parsePoseLine(const std::string& text, const std::string& path, std::size_t line_number)
{
  std::vector<double> numbers;
  if (!parseNumbers(text, numbers))
  {
    throw std::runtime_error(location(path, line_number) + ": not a list of finite numbers");
  }
  if (numbers.size() != 12)
  {
    throw std::runtime_error(location(path, line_number) + ": expected 12 numbers, got " +
                             std::to_string(numbers.size()));
  }
  return poseFromRowMajor(numbers);
}

std::ifstream openForReading(const std::string& path)
{
  std::ifstream in(path);
  if (!in)
  {
    throw std::runtime_error("cannot open '" + path + "' for reading");
  }
  return in;
}

// Calls `handle(line, line_number)` for every non-blank line of the file at `path`.
template <typename Handler>
void forEachLine(const std::string& path, Handler handle)
{
  std::ifstream in = openForReading(path);
  std::string line;
  std::size_t line_number = 0;
  while (std::getline(in, line))
  {
    ++line_number;
    if (!isBlank(line))
    {
      handle(line, line_number);
    }
  }
  if (in.bad())
  {
    throw std::runtime_error("error while reading '" + path + "'");
  }
}

// RAII wrapper around a C stdio file opened for writing.
class OutputFile
{
public:
  explicit OutputFile(const std::string& path) : path_(path), file_(std::fopen(path.c_str(), "w"))
  {
    if (file_ == nullptr)
    {
      throw std::runtime_error("cannot open '" + path + "' for writing");
    }
  }
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  ~OutputFile()
  {
    if (file_ != nullptr)
    {
      std::fclose(file_);
    }
  }

  std::FILE* get() const { return file_; }

  // Flushes and closes; throws if anything failed to be written.
  void close()
  {
    const bool failed = std::ferror(file_) != 0;
    const int rc = std::fclose(file_);
    file_ = nullptr;
    if (failed || rc != 0)
    {
      throw std::runtime_error("error while writing '" + path_ + "'");
    }
  }

private:
  std::string path_;
  std::FILE* file_;
};

}  // namespace

Trajectory readKittiPoses(const std::string& path)
{
  Trajectory poses;
  forEachLine(path, [&](const std::string& line, std::size_t line_number)
              { poses.push_back(parsePoseLine(line, path, line_number)); });
  return poses;
}

void writeKittiPoses(const std::string& path, const Trajectory& poses)
{
  OutputFile out(path);
  for (const Eigen::Isometry3d& pose : poses)
  {
    const Eigen::Matrix4d& m = pose.matrix();
    for (int r = 0; r < 3; ++r)
    {
      for (int c = 0; c < 4; ++c)
      {
        std::fprintf(out.get(), (r == 0 && c == 0) ? "%.16e" : " %.16e", m(r, c));
      }
    }
    std::fputc('\n', out.get());
  }
  out.close();
}

void writeTumTrajectory(const std::string& path, const Trajectory& poses, const std::vector<double>& stamps)
{
  if (stamps.size() != poses.size())
  {
    throw std::invalid_argument("writeTumTrajectory: " + std::to_string(poses.size()) + " poses but " +
                                std::to_string(stamps.size()) + " timestamps");
  }
  OutputFile out(path);
  for (std::size_t i = 0; i < poses.size(); ++i)
  {
    const Eigen::Vector3d t = poses[i].translation();
    Eigen::Quaterniond q(Eigen::Matrix3d(poses[i].linear()));
    q.normalize();
    if (q.w() < 0.0)
    {
      q.coeffs() *= -1.0;
    }
    std::fprintf(out.get(), "%.9f %.9e %.9e %.9e %.9e %.9e %.9e %.9e\n", stamps[i], t.x(), t.y(), t.z(), q.x(), q.y(),
                 q.z(), q.w());
  }
  out.close();
}

Eigen::Isometry3d readKittiCalibTr(const std::string& path)
{
  std::ifstream in = openForReading(path);
  std::string line;
  std::size_t line_number = 0;
  while (std::getline(in, line))
  {
    ++line_number;
    std::istringstream stream(line);
    std::string key;
    if (!(stream >> key) || key != "Tr:")
    {
      continue;
    }
    std::string rest;
    std::getline(stream, rest);
    return parsePoseLine(rest, path, line_number);
  }
  throw std::runtime_error("'" + path + "' has no 'Tr:' line");
}

std::vector<double> readTimes(const std::string& path)
{
  std::vector<double> times;
  std::vector<double> numbers;
  forEachLine(path,
              [&](const std::string& line, std::size_t line_number)
              {
                if (!parseNumbers(line, numbers) || numbers.size() != 1)
                {
                  throw std::runtime_error(location(path, line_number) + ": expected one timestamp");
                }
                times.push_back(numbers.front());
              });
  return times;
}

}  // namespace eval
}  // namespace aloam
