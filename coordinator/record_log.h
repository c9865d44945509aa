// BlockLog<T>: an append-only list in fixed-size blocks that never move. The owner appends under
// its lock; Snapshot() hands out the elements so far as a view that stays valid and unchanged while
// the log grows (and after it is destroyed), so a long scan over them (the backlog of a worker's
// grown region, JobManager::AddTileRegion) runs without the lock. A reader of a view and the
// writer never touch the same element: the writer only fills slots past every view handed out.
// RecordLog holds a job's merged records in arrival order; GlobalCache also keeps a log of compact
// record entries per spatial cell.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "cache/irradiance_record.h"

namespace irfarm {

template <typename T, size_t kBlock = 4096>
class BlockLog {
  struct Block {
    std::array<T, kBlock> items;
  };

 public:
  class View {
   public:
    size_t size() const { return size_; }
    const T& operator[](size_t i) const { return blocks_[i / kBlock]->items[i % kBlock]; }
    std::vector<T> ToVector() const {
      std::vector<T> out;
      out.reserve(size_);
      for (size_t i = 0; i < size_; ++i) out.push_back((*this)[i]);
      return out;
    }

   private:
    friend class BlockLog;
    std::vector<std::shared_ptr<const Block>> blocks_;
    size_t size_ = 0;
  };

  void Append(const T& item) {
    if (size_ % kBlock == 0) blocks_.push_back(std::make_shared<Block>());
    blocks_.back()->items[size_ % kBlock] = item;
    ++size_;
  }
  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  const T& operator[](size_t i) const { return blocks_[i / kBlock]->items[i % kBlock]; }
  View Snapshot() const {
    View v;
    v.blocks_.assign(blocks_.begin(), blocks_.end());
    v.size_ = size_;
    return v;
  }
  std::vector<T> ToVector() const { return Snapshot().ToVector(); }

 private:
  std::vector<std::shared_ptr<Block>> blocks_;
  size_t size_ = 0;
};

using RecordLog = BlockLog<IrradianceRecord>;

}  // namespace irfarm
