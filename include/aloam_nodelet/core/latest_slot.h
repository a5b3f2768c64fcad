// Hand-over of the newest item from a producer to a consumer that may be slower: an older item not yet taken
// is replaced (and counted), never queued.
#pragma once

#include <cstddef>
#include <mutex>
#include <optional>
#include <utility>

namespace aloam
{
template <typename T>
class LatestSlot
{
public:
  /// Puts `item` in the slot; true when it replaced one that was never taken.
  bool put(T item)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool replaced = item_.has_value();
    skipped_ += replaced ? 1 : 0;
    item_ = std::move(item);
    return replaced;
  }

  /// The item, if there is one; the slot is empty afterwards.
  std::optional<T> take()
  {
    std::lock_guard<std::mutex> lock(mutex_);
    std::optional<T> out;
    out.swap(item_);
    return out;
  }

  bool empty() const
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return !item_.has_value();
  }

  /// Items replaced before they were taken, since construction.
  std::size_t skipped() const
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return skipped_;
  }

private:
  mutable std::mutex mutex_;
  std::optional<T> item_;
  std::size_t skipped_ = 0;
};

}  // namespace aloam
