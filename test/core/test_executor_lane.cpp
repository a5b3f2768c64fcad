// The executor's lane without the privilege to leave SCHED_IDLE (Mode kWithRunner: the idle-priority gate
// hands due jobs to a second, normal-priority runner thread). Tests here run as root, where the lane takes
// the one-thread path, so the scenarios run in a child process that first gives up that privilege: it
// lowers RLIMIT_NICE to 0 and drops CAP_SYS_NICE (raw capget/capset, no libcap). The child is this binary
// run again (fork, then exec at once: the parent may have threads, e.g. a sanitizer's) with an environment
// variable that makes it run the scenarios before main and exit. It reports each failed check through a
// pipe and exits 0 only if all held; the parent asserts on its exit status.
//
// Nothing waits for a time: the child waits on conditions, and the parent gives it minutes, for a loaded
// 2-core machine.
#include <fcntl.h>
#include <linux/capability.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "thread_support.h"
#include "aloam_nodelet/core/executor.h"

namespace aloam
{
namespace
{
using Clock = std::chrono::steady_clock;

constexpr int kChildPassed = 0;
constexpr int kChildFailed = 1;
constexpr int kChildDropRefused = 77;  // the privilege could not be given up: the parent skips
// Set in the child's environment to the pipe's write end.
constexpr char kChildVariable[] = "ALOAM_EXECUTOR_LANE_CHILD";
// Far beyond what the child needs (well under a second unloaded); a hung child is killed and reported.
constexpr auto kChildTimeout = std::chrono::minutes(4);
// How long the child waits for one condition (the idle-priority gate may be starved for a while).
constexpr auto kConditionTimeout = std::chrono::minutes(1);

using aloam_test::Latch;
using aloam_test::threadId;

std::vector<pid_t> threadsOfThisProcess()
{
  std::vector<pid_t> tids;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task"))
  {
    tids.push_back(static_cast<pid_t>(std::stol(entry.path().filename().string())));
  }
  return tids;
}

/// The threads of `now` that `before` did not have. Other libraries may start and end threads of their own
/// (one was seen alive at the child's start and gone a moment later), so the executor's threads are told
/// apart by identity, not by the process's thread count.
std::vector<pid_t> threadsAddedTo(const std::vector<pid_t>& before, const std::vector<pid_t>& now)
{
  std::vector<pid_t> added;
  for (const pid_t tid : now)
  {
    if (std::find(before.begin(), before.end(), tid) == before.end())
    {
      added.push_back(tid);
    }
  }
  return added;
}

/// What /proc says about one thread of this process.
struct ThreadInfo
{
  char state = '?';  // R running, S sleeping, ...
  int nice = 0;
  int policy = -1;
  long voluntary_switches = -1;  // times it went to sleep on its own
};

std::optional<ThreadInfo> threadInfo(pid_t tid)
{
  const std::string dir = "/proc/self/task/" + std::to_string(tid);
  std::ifstream stat_file(dir + "/stat");
  std::string stat;
  if (!std::getline(stat_file, stat))
  {
    return std::nullopt;
  }
  // Fields after the command name (which may hold spaces) start with field 3, the state; the nice value
  // is field 19 and the policy field 41 (proc(5)).
  const std::size_t close = stat.rfind(')');
  if (close == std::string::npos)
  {
    return std::nullopt;
  }
  std::istringstream fields(stat.substr(close + 1));
  std::vector<std::string> field;
  for (std::string f; fields >> f;)
  {
    field.push_back(f);
  }
  if (field.size() < 39)
  {
    return std::nullopt;
  }
  ThreadInfo info;
  info.state = field[0][0];
  info.nice = std::stoi(field[16]);
  info.policy = std::stoi(field[38]);
  std::ifstream status(dir + "/status");
  for (std::string line; std::getline(status, line);)
  {
    if (line.rfind("voluntary_ctxt_switches:", 0) == 0)
    {
      info.voluntary_switches = std::stol(line.substr(line.find(':') + 1));
    }
  }
  return info;
}

/// The lane's gate: where leaving SCHED_IDLE is refused it stays there (or at nice 19 where SCHED_IDLE
/// itself is refused) for good, unlike every other thread, which has the nice value `normal_nice`.
bool isIdlePriority(const ThreadInfo& info, int normal_nice)
{
  return info.policy == SCHED_IDLE || info.nice > normal_nice;
}

template <typename Condition>
bool waitUntil(Condition condition)
{
  const auto give_up = Clock::now() + kConditionTimeout;
  while (!condition())
  {
    if (Clock::now() > give_up)
    {
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

/// Gives up what lets a thread leave SCHED_IDLE again: RLIMIT_NICE above 0 and CAP_SYS_NICE. Empty if
/// done, else why it was refused.
std::string dropNicePrivilege()
{
  const rlimit none{ 0, 0 };
  if (setrlimit(RLIMIT_NICE, &none) != 0)
  {
    return std::string("setrlimit(RLIMIT_NICE, 0): ") + std::strerror(errno);
  }
  __user_cap_header_struct header{};
  header.version = _LINUX_CAPABILITY_VERSION_3;
  header.pid = 0;  // this thread; threads started later inherit its sets
  __user_cap_data_struct data[_LINUX_CAPABILITY_U32S_3] = {};
  if (syscall(SYS_capget, &header, data) != 0)
  {
    return std::string("capget: ") + std::strerror(errno);
  }
  const unsigned index = CAP_SYS_NICE / 32;
  const std::uint32_t bit = 1u << (CAP_SYS_NICE % 32);
  data[index].effective &= ~bit;
  data[index].permitted &= ~bit;
  data[index].inheritable &= ~bit;
  if (syscall(SYS_capset, &header, data) != 0)
  {
    return std::string("capset without CAP_SYS_NICE: ") + std::strerror(errno);
  }
  return {};
}

/// Whether a thread that lowered itself to idle priority (as the gate does) can come back: tried on a
/// thread of its own, so that this one keeps its priority (threads inherit it).
bool canLeaveIdlePriority()
{
  bool left = false;
  std::thread probe(
      [&]
      {
        const id_t tid = static_cast<id_t>(threadId());
        int policy = SCHED_OTHER;
        sched_param normal{};
        pthread_getschedparam(pthread_self(), &policy, &normal);
        const int nice = getpriority(PRIO_PROCESS, tid);
        sched_param idle{};
        if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &idle) != 0)
        {
          setpriority(PRIO_PROCESS, tid, 19);
        }
        left = pthread_setschedparam(pthread_self(), policy, &normal) == 0 && setpriority(PRIO_PROCESS, tid, nice) == 0;
      });
  probe.join();
  return left;
}

/// The child's record of failed checks (each named by what was expected), sent to the parent through a pipe.
class ChildReport
{
public:
  explicit ChildReport(int fd) : fd_(fd) {}

  void note(const std::string& text)
  {
    const std::string line = text + "\n";
    for (std::size_t done = 0; done < line.size();)
    {
      const ssize_t n = write(fd_, line.data() + done, line.size() - done);
      if (n <= 0)
      {
        return;
      }
      done += static_cast<std::size_t>(n);
    }
  }
  void check(bool ok, const std::string& what)
  {
    if (!ok)
    {
      failed_ = true;
      note("FAILED, expected: " + what);
    }
  }
  bool failed() const { return failed_; }

private:
  int fd_;
  bool failed_ = false;
};

/// What one run of a job saw.
struct RunRecord
{
  std::atomic<pid_t> tid{ 0 };
  std::atomic<int> policy{ -1 };
  std::atomic<int> nice{ 99 };
  std::atomic<Clock::rep> started_at{ 0 };

  void record()
  {
    started_at = Clock::now().time_since_epoch().count();
    tid = threadId();
    policy = sched_getscheduler(0);
    nice = getpriority(PRIO_PROCESS, static_cast<id_t>(threadId()));
  }
};

/// The lane scenarios, in the child once the privilege is gone. Returns the child's exit status.
int runUnprivilegedLane(ChildReport& report)
{
  const pid_t main_tid = threadId();
  const int main_nice = getpriority(PRIO_PROCESS, static_cast<id_t>(main_tid));
  const int main_policy = sched_getscheduler(0);
  const std::vector<pid_t> threads_at_start = threadsOfThisProcess();
  std::vector<pid_t> started;  // every thread the executor started
  {
    Executor executor(2);
    const std::vector<pid_t> with_helpers = threadsOfThisProcess();

    // Requests: the runner runs them at the creator's priority, not the gate's.
    RunRecord on_request;
    Executor::Job requested = executor.makeJob([&] { on_request.record(); });
    report.check(!executor.laneIsSingleThread(), "laneIsSingleThread() false without the privilege");
    const std::vector<pid_t> tids = threadsOfThisProcess();
    const std::size_t lane_threads = threadsAddedTo(with_helpers, tids).size();
    report.check(lane_threads == 2, "the lane is two threads (gate and runner): " + std::to_string(lane_threads) +
                                        " threads started by the first job");
    started = threadsAddedTo(threads_at_start, tids);
    std::vector<pid_t> idle;
    for (const pid_t tid : tids)
    {
      const std::optional<ThreadInfo> info = threadInfo(tid);
      if (info && isIdlePriority(*info, main_nice))
      {
        idle.push_back(tid);
      }
    }
    report.check(idle.size() == 1,
                 "exactly one thread (the gate) at idle priority, found " + std::to_string(idle.size()));
    const pid_t gate = idle.empty() ? 0 : idle.front();

    requested.request();
    requested.waitForRuns(1);
    report.check(requested.runs() == 1, "request(): one run");
    report.check(on_request.tid != main_tid && on_request.tid != gate, "request(): run on the runner thread");
    report.check(on_request.policy == main_policy && on_request.nice == main_nice,
                 "request(): run at normal priority (policy " + std::to_string(on_request.policy.load()) + ", nice " +
                     std::to_string(on_request.nice.load()) + ")");
    const pid_t runner = on_request.tid;

    // A deadline: not run before it, then run by the runner.
    const Clock::time_point deadline = Clock::now() + std::chrono::milliseconds(30);
    requested.requestBy(deadline);
    requested.waitForRuns(2);
    report.check(requested.runs() == 2, "requestBy(): one more run");
    report.check(on_request.started_at >= deadline.time_since_epoch().count(),
                 "requestBy(): not run before its deadline");
    report.check(on_request.tid == runner, "requestBy(): run on the runner thread");

    // runIfPending takes back a job the gate handed to the runner while the runner is busy with another.
    Latch blocker_started, blocker_release;
    Executor::Job blocker = executor.makeJob(
        [&]
        {
          blocker_started.open();
          blocker_release.wait();
        });
    RunRecord taken_back;
    Executor::Job handed = executor.makeJob([&] { taken_back.record(); });
    std::atomic<bool> after_ran{ false };
    std::atomic<bool> handed_ran_before_after{ false };
    Executor::Job after = executor.makeJob(
        [&]
        {
          handed_ran_before_after = handed.runs() > 1;
          after_ran = true;
        });
    blocker.request();
    blocker_started.wait();  // the runner is busy until blocker_release
    // The gate hands the job over and goes back to sleep: wait for it to fall asleep again after the
    // request (its voluntary switches grow), so that the job is handed, not merely requested. No assertion
    // below depends on this; it only makes sure the hand-back path is the one taken.
    std::optional<ThreadInfo> before;
    const bool gate_asleep = waitUntil(
        [&]
        {
          // Asleep and staying so (two looks 10 ms apart): not on its way back from handing `blocker`.
          const std::optional<ThreadInfo> first = threadInfo(gate);
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
          before = threadInfo(gate);
          return first && before && first->state == 'S' && before->state == 'S' &&
                 first->voluntary_switches == before->voluntary_switches;
        });
    report.check(gate_asleep, "the gate sleeps while the runner is busy");
    const long switches_before = before ? before->voluntary_switches : 0;
    handed.request();
    const bool gate_handed = waitUntil(
        [&]
        {
          const std::optional<ThreadInfo> now = threadInfo(gate);
          return now && now->state == 'S' && now->voluntary_switches > switches_before;
        });
    report.check(gate_handed, "the gate woke for the request and slept again");
    report.check(handed.runIfPending(), "runIfPending() takes back a handed, not started job");
    report.check(taken_back.tid == main_tid, "runIfPending(): run on the caller");
    report.check(handed.runs() == 1, "runIfPending(): one run");
    report.check(blocker.runs() == 0, "runIfPending() did not wait for the busy runner");
    report.check(!handed.runIfPending(), "runIfPending(): the request is used up");
    // The runner takes handed jobs in order: had the taken-back one stayed on its list, it would run again
    // before `after`.
    after.request();
    blocker_release.open();
    after.waitForRuns(1);
    blocker.waitForRuns(1);
    report.check(after_ran && !handed_ran_before_after, "the taken-back job is not run again by the runner");
    report.check(handed.runs() == 1, "the taken-back job ran once, has " + std::to_string(handed.runs()));

    // Destroying a Job waits for its run on the runner.
    Latch slow_started, slow_release;
    std::atomic<bool> slow_finished{ false };
    auto slow = std::make_unique<Executor::Job>(executor.makeJob(
        [&]
        {
          slow_started.open();
          slow_release.wait();
          slow_finished = true;
        }));
    slow->request();
    slow_started.wait();
    std::atomic<pid_t> destroyer_tid{ 0 };
    std::atomic<bool> destroyed{ false };
    std::atomic<bool> finished_when_destroyed{ false };
    std::thread destroyer(
        [&]
        {
          destroyer_tid = threadId();
          slow.reset();
          finished_when_destroyed = slow_finished.load();
          destroyed = true;
        });
    // Let the destroyer block in the destructor (it sleeps there) before the job may finish.
    const bool blocked = waitUntil(
        [&]
        {
          if (destroyed || destroyer_tid == 0)
          {
            return destroyed.load();
          }
          const std::optional<ThreadInfo> info = threadInfo(destroyer_tid);
          return info && info->state == 'S';
        });
    report.check(blocked, "the destroyer blocked");
    report.check(!destroyed, "destroying a Job waits while its run goes on");
    slow_release.open();
    destroyer.join();
    report.check(finished_when_destroyed, "the run finished before its Job's destructor returned");
  }
  // Every thread of the executor, the lane's two included, is joined with it.
  const auto still_alive = [&] { return started.size() - threadsAddedTo(threadsOfThisProcess(), started).size(); };
  const bool joined = waitUntil([&] { return still_alive() == 0; });
  report.check(started.size() >= 3 && joined, "the executor's threads end with it: " + std::to_string(still_alive()) +
                                                  " of its " + std::to_string(started.size()) + " still alive");
  return report.failed() ? kChildFailed : kChildPassed;
}

int childMain(int fd)
{
  ChildReport report(fd);
  const std::string refused = dropNicePrivilege();
  if (!refused.empty())
  {
    report.note(refused);
    return kChildDropRefused;
  }
  // The drop was granted; it must also work, or the lane below is not the one under test.
  report.check(!canLeaveIdlePriority(), "no thread leaves idle priority once the privilege is dropped");
  if (report.failed())
  {
    return kChildFailed;
  }
  report.note("privilege dropped: RLIMIT_NICE 0, no CAP_SYS_NICE");
  return runUnprivilegedLane(report);
}

/// In the child, before main (and before gtest): the scenarios, then exit.
struct ChildEntry
{
  ChildEntry()
  {
    if (const char* fd = std::getenv(kChildVariable))
    {
      _exit(childMain(std::atoi(fd)));
    }
  }
} child_entry;

TEST(ExecutorLane, WithoutThePrivilegeToLeaveIdleARunnerThreadRunsTheJobs)
{
  int fds[2];
  ASSERT_EQ(pipe(fds), 0) << std::strerror(errno);
  // The child's environment, made before the fork: between fork and exec only async-signal-safe calls.
  std::vector<std::string> variables;
  for (char** v = environ; *v != nullptr; ++v)
  {
    if (std::string(*v).rfind(std::string(kChildVariable) + "=", 0) != 0)
    {
      variables.emplace_back(*v);
    }
  }
  variables.push_back(std::string(kChildVariable) + "=" + std::to_string(fds[1]));
  std::vector<char*> envp;
  for (std::string& v : variables)
  {
    envp.push_back(v.data());
  }
  envp.push_back(nullptr);
  char self[] = "/proc/self/exe";
  char* argv[] = { self, nullptr };
  const pid_t child = fork();
  ASSERT_GE(child, 0) << std::strerror(errno);
  if (child == 0)
  {
    close(fds[0]);
    execve(self, argv, envp.data());
    _exit(127);
  }
  close(fds[1]);
  fcntl(fds[0], F_SETFL, O_NONBLOCK);
  std::string output;
  const auto give_up = Clock::now() + kChildTimeout;
  bool timed_out = false;
  while (true)
  {
    if (Clock::now() > give_up)
    {
      timed_out = true;
      break;
    }
    pollfd pfd{ fds[0], POLLIN, 0 };
    if (poll(&pfd, 1, 1000) <= 0)
    {
      continue;
    }
    char buffer[512];
    const ssize_t n = read(fds[0], buffer, sizeof(buffer));
    if (n > 0)
    {
      output.append(buffer, static_cast<std::size_t>(n));
    }
    else if (n == 0 || errno != EAGAIN)
    {
      break;  // the child closed the pipe (it exited)
    }
  }
  close(fds[0]);
  if (timed_out)
  {
    kill(child, SIGKILL);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  std::printf("child:\n%s", output.c_str());
  ASSERT_FALSE(timed_out) << "the child hung (killed after " << kChildTimeout.count() << " min):\n" << output;
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) != 127)
      << "the child could not run or died (exit " << (WIFEXITED(status) ? WEXITSTATUS(status) : -1) << ", signal "
      << (WIFSIGNALED(status) ? WTERMSIG(status) : 0) << "):\n"
      << output;
  if (WEXITSTATUS(status) == kChildDropRefused)
  {
    GTEST_SKIP() << "cannot give up the privilege to leave SCHED_IDLE here: " << output;
  }
  EXPECT_EQ(WEXITSTATUS(status), kChildPassed) << output;
}

}  // namespace
}  // namespace aloam
