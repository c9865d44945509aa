// RecordLog: a job's merged records in arrival order, append-only, in fixed-size blocks that never
// move. The owner appends under its lock; View() hands out the records so far as a view that
// stays valid and unchanged while the log grows (and after it is destroyed), so a long scan over
// them (the backlog of a worker's grown region, JobManager::AddTileRegion) runs without the lock.
// A reader of a prefix and the writer never touch the same record: the writer only fills slots
// past every prefix handed out.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <vector>

#include "cache/irradiance_record.h"

namespace irfarm {

class RecordLog {
  static constexpr size_t kBlock = 4096;
  struct Block {
    std::array<IrradianceRecord, kBlock> records;
  };

 public:
  class Prefix {
   public:
    size_t size() const { return size_; }
    const IrradianceRecord& operator[](size_t i) const {
      return blocks_[i / kBlock]->records[i % kBlock];
    }

   private:
    friend class RecordLog;
    std::vector<std::shared_ptr<const Block>> blocks_;
    size_t size_ = 0;
  };

  void Append(const IrradianceRecord& r) {
    if (size_ % kBlock == 0) blocks_.push_back(std::make_shared<Block>());
    blocks_.back()->records[size_ % kBlock] = r;
    ++size_;
  }
  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  const IrradianceRecord& operator[](size_t i) const {
    return blocks_[i / kBlock]->records[i % kBlock];
  }
  Prefix View() const {
    Prefix p;
    p.blocks_.assign(blocks_.begin(), blocks_.end());
    p.size_ = size_;
    return p;
  }
  std::vector<IrradianceRecord> ToVector() const {
    std::vector<IrradianceRecord> out;
    out.reserve(size_);
    for (size_t i = 0; i < size_; ++i) out.push_back((*this)[i]);
    return out;
  }

 private:
  std::vector<std::shared_ptr<Block>> blocks_;
  size_t size_ = 0;
};

}  // namespace irfarm
