// RecordTag: a 64-bit tag carried inside a synthetic irradiance record through the coordinator,
// for the scale simulation (scale_sim.cc): which simulated worker published it, its sequence
// number there and its send time. The coordinator validates, stores and forwards a record's ten
// floats unchanged, so the tag rides in the low 16 mantissa bits of irradiance r, g, b and the
// radius (a relative change below 2^-7 of values the simulation draws anyway). The receiver reads
// it back with a few bit operations per record, no lookup in a shared table.
#pragma once

#include <cstdint>
#include <cstring>

#include "cache/irradiance_record.h"

namespace irfarm {

struct RecordTag {
  uint32_t sender = 0;    // simulated worker index, 12 bits (< 4096)
  uint32_t sequence = 0;  // per sender, 20 bits (wraps after 1,048,576 records)
  uint32_t send_us = 0;   // steady clock, microseconds, modulo 2^32 (differences wrap correctly)

  // Sender and sequence alone: identifies the record (the smoke check's sets).
  uint64_t Id() const { return (uint64_t(sender & 0xfffu) << 20) | (sequence & 0xfffffu); }
};

namespace record_tag_internal {

inline uint32_t Bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}
inline float WithLow16(float f, uint32_t low) {
  const uint32_t u = (Bits(f) & 0xffff0000u) | (low & 0xffffu);
  float out;
  std::memcpy(&out, &u, 4);
  return out;
}

}  // namespace record_tag_internal

// Writes `tag` into r (irradiance and radius must be normal positive floats; they change by less
// than 2^-7 of their value).
inline void PutTag(const RecordTag& tag, IrradianceRecord* r) {
  using record_tag_internal::WithLow16;
  const uint64_t v = (tag.Id() << 32) | tag.send_us;
  r->irradiance.x = WithLow16(r->irradiance.x, uint32_t(v));
  r->irradiance.y = WithLow16(r->irradiance.y, uint32_t(v >> 16));
  r->irradiance.z = WithLow16(r->irradiance.z, uint32_t(v >> 32));
  r->radius = WithLow16(r->radius, uint32_t(v >> 48));
}

// The tag of a record packed as kFloatsPerRecord floats (service/record_codec.h: irradiance at
// 6..8, radius at 9).
inline RecordTag GetTag(const float* packed) {
  using record_tag_internal::Bits;
  const uint64_t v =
      uint64_t(Bits(packed[6]) & 0xffffu) | (uint64_t(Bits(packed[7]) & 0xffffu) << 16) |
      (uint64_t(Bits(packed[8]) & 0xffffu) << 32) | (uint64_t(Bits(packed[9]) & 0xffffu) << 48);
  RecordTag t;
  t.send_us = uint32_t(v);
  t.sequence = uint32_t(v >> 32) & 0xfffffu;
  t.sender = uint32_t(v >> 52) & 0xfffu;
  return t;
}

}  // namespace irfarm
