// A thin RAII layer over Cyclone DDS's C API: participants, topics, typed
// writers and readers, and WaitSets (no sleep-polling). Services use it;
// the mathematics never includes it.
#pragma once

#include <dds/dds.h>

#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace artms::dds {

// Error from a DDS call, with Cyclone's return code text.
class DdsError : public std::runtime_error {
 public:
  DdsError(const std::string& what, dds_return_t rc);
};

// Applies the project's loopback-only, multicast-off Cyclone configuration
// (config/cyclonedds-loopback.xml, DESIGN.md section 9) when CYCLONEDDS_URI is
// unset. Called by every Participant; idempotent.
void ensure_loopback_config();

// The DDS domain of a run: ARTMS_DDS_DOMAIN if set (the launcher sets a
// different one per run so that concurrent runs never meet), else 0.
std::uint32_t domain_from_environment();

struct QosProfile {
  bool reliable = true;
  bool transient_local = false;
  int history_depth = 0;          // 0 = KEEP_ALL
  std::int64_t lifespan_ns = 0;   // 0 = infinite
  std::vector<std::string> partitions;
};

class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t handle) : handle_(handle) {}
  ~Entity();
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;
  Entity(Entity&& other) noexcept : handle_(other.handle_) { other.handle_ = 0; }
  Entity& operator=(Entity&& other) noexcept;
  [[nodiscard]] dds_entity_t handle() const { return handle_; }

 protected:
  // Gives up ownership without deleting (the caller deleted it another way).
  dds_entity_t release() { return std::exchange(handle_, 0); }
  void adopt(dds_entity_t h) { handle_ = h; }

 private:
  dds_entity_t handle_ = 0;
};

class Participant : public Entity {
 public:
  explicit Participant(std::uint32_t domain_id);
};

class Topic : public Entity {
 public:
  Topic(const Participant& p, const dds_topic_descriptor_t* descriptor, const std::string& name);
};

namespace detail {
dds_entity_t create_writer(const Participant& p, const Topic& t, const QosProfile& q);
dds_entity_t create_reader(const Participant& p, const Topic& t, const QosProfile& q);
void write(dds_entity_t writer, const void* sample);
// Moves a writer into the partitions of q. Tries dds_set_qos on its
// publisher (the partition policy is changeable in the DDS specification);
// Cyclone DDS 0.10 answers UNSUPPORTED for an enabled publisher, so then the
// publisher (and with it the writer) is deleted and a writer with the same
// QoS is created in a new publisher with the new partitions: the matches of
// the old writer disappear, the new one matches the readers of its
// partitions. Returns the writer's (possibly new) handle.
dds_entity_t repartition_writer(dds_entity_t writer, const Participant& p, const Topic& t, const QosProfile& q);
int matched(dds_entity_t entity, bool is_writer);
bool wait_for_acks(dds_entity_t writer, double timeout_s);
// Takes every available sample; calls visit(sample_ptr) for valid data.
template <typename F>
int take_each(dds_entity_t reader, F&& visit) {
  constexpr int kBatch = 64;
  int total = 0;
  for (;;) {
    void* samples[kBatch] = {nullptr};
    dds_sample_info_t infos[kBatch];
    const dds_return_t n = dds_take(reader, samples, infos, kBatch, kBatch);
    if (n < 0) throw DdsError("dds_take", n);
    if (n == 0) break;
    try {
      for (int k = 0; k < n; ++k) {
        if (infos[k].valid_data) {
          visit(samples[k]);
          ++total;
        }
      }
    } catch (...) {
      dds_return_loan(reader, samples, n);
      throw;
    }
    dds_return_loan(reader, samples, n);
    if (n < kBatch) break;
  }
  return total;
}
}  // namespace detail

template <typename T>
class Writer : public Entity {
 public:
  Writer(const Participant& p, const Topic& t, const QosProfile& q)
      : Entity(detail::create_writer(p, t, q)) {}
  void write(const T& sample) { detail::write(handle(), &sample); }
  // Blocks until every matched reliable reader acknowledged all samples;
  // false on timeout.
  bool wait_for_acks(double timeout_s) { return detail::wait_for_acks(handle(), timeout_s); }
  [[nodiscard]] int matched_readers() const { return detail::matched(handle(), true); }
  // Switches the writer's publisher to q.partitions (see detail::repartition_writer).
  void set_partitions(const Participant& p, const Topic& t, const QosProfile& q) {
    adopt(detail::repartition_writer(release(), p, t, q));
  }
};

template <typename T>
class Reader : public Entity {
 public:
  Reader(const Participant& p, const Topic& t, const QosProfile& q)
      : Entity(detail::create_reader(p, t, q)) {}
  // Calls visit(const T&) for every sample available now; returns how many.
  template <typename F>
  int take_each(F&& visit) {
    return detail::take_each(handle(), [&](const void* s) { visit(*static_cast<const T*>(s)); });
  }
  [[nodiscard]] int matched_writers() const { return detail::matched(handle(), false); }
};

// Waits for data on any attached reader (a read condition per reader).
class WaitSet : public Entity {
 public:
  explicit WaitSet(const Participant& p);
  void attach(dds_entity_t reader);
  // Returns true if some attached reader has data, false on timeout.
  bool wait(double timeout_s);

 private:
  std::vector<Entity> conditions_;
};

// Blocks until every listed writer/reader has at least `expected` matches
// (discovery), waiting on their matched-status conditions in a WaitSet.
// Throws std::runtime_error listing what is still unmatched at the timeout,
// or when `stop` becomes true.
struct MatchExpectation {
  std::string name;
  dds_entity_t entity;
  bool is_writer;
  int expected;
};
void wait_for_matches(const Participant& p, const std::vector<MatchExpectation>& expected,
                      double timeout_s, const volatile std::atomic<bool>* stop = nullptr);

// Copies a C string field (bounded string) safely.
std::string to_string(const char* bounded, std::size_t capacity);
// Writes text into a bounded string field of `capacity` bytes (truncating).
void copy_string(char* dst, std::size_t capacity, const std::string& src);

}  // namespace artms::dds
