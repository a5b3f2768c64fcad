#include "aloam_nodelet/core/parallel.h"

namespace aloam
{
namespace detail
{
namespace
{
struct TeamPool
{
  std::mutex mutex;
  std::vector<std::unique_ptr<HelperTeam>> all;  // owns every team ever made
  std::vector<HelperTeam*> idle;                 // not lent out; the back was returned last
};

TeamPool& pool()
{
  // Never destroyed: a stage may still be inside a parallel region while the process exits, and idle
  // helpers sleep without cost.
  static TeamPool* const instance = new TeamPool;
  return *instance;
}
}  // namespace

HelperTeam* lendTeam(std::size_t count)
{
  TeamPool& p = pool();
  HelperTeam* team = nullptr;
  {
    std::lock_guard<std::mutex> lock(p.mutex);
    if (p.idle.empty())
    {
      p.all.push_back(std::make_unique<HelperTeam>());
      team = p.all.back().get();
    }
    else
    {
      team = p.idle.back();
      p.idle.pop_back();
    }
  }
  // Lent to this caller alone now: grown outside the lock.
  while (team->size() < count)
  {
    team->push_back(std::make_unique<Helper>());
  }
  return team;
}

void returnTeam(HelperTeam* team)
{
  TeamPool& p = pool();
  std::lock_guard<std::mutex> lock(p.mutex);
  p.idle.push_back(team);
}

}  // namespace detail
}  // namespace aloam
