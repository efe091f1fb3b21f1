#include "artms/dds/dds.hpp"

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <string>

#include "artms/io/paths.hpp"

namespace artms::dds {

DdsError::DdsError(const std::string& what, dds_return_t rc)
    : std::runtime_error(what + " failed: " + dds_strretcode(rc)) {}

void ensure_loopback_config() {
  if (std::getenv("CYCLONEDDS_URI") == nullptr) {
    const std::string uri = std::string("file://") + io::config_dir() + "/cyclonedds-loopback.xml";
    setenv("CYCLONEDDS_URI", uri.c_str(), 0);
  }
}

std::uint32_t domain_from_environment() {
  const char* d = std::getenv("ARTMS_DDS_DOMAIN");
  if (d == nullptr || *d == '\0') return 0;
  char* end = nullptr;
  const long v = std::strtol(d, &end, 10);
  if (*end != '\0' || v < 0 || v > 230) {
    throw std::invalid_argument(std::string("ARTMS_DDS_DOMAIN must be 0..230, got '") + d + "'");
  }
  return static_cast<std::uint32_t>(v);
}

Entity::~Entity() {
  if (handle_ > 0) dds_delete(handle_);
}

Entity& Entity::operator=(Entity&& other) noexcept {
  if (this != &other) {
    if (handle_ > 0) dds_delete(handle_);
    handle_ = other.handle_;
    other.handle_ = 0;
  }
  return *this;
}

namespace {
dds_entity_t checked(dds_entity_t h, const char* what) {
  if (h < 0) throw DdsError(what, h);
  return h;
}

dds_qos_t* make_qos(const QosProfile& q) {
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, q.reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                       DDS_SECS(10));
  dds_qset_durability(qos, q.transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL
                                             : DDS_DURABILITY_VOLATILE);
  if (q.history_depth > 0) {
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, q.history_depth);
  } else {
    dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  }
  if (q.lifespan_ns > 0) dds_qset_lifespan(qos, q.lifespan_ns);
  if (!q.partitions.empty()) {
    std::vector<const char*> names;
    for (const auto& s : q.partitions) names.push_back(s.c_str());
    dds_qset_partition(qos, static_cast<uint32_t>(names.size()), names.data());
  }
  return qos;
}

// Publisher/subscriber per writer/reader so that partitions apply per entity.
dds_entity_t with_group(dds_entity_t participant, const QosProfile& q, bool publisher) {
  dds_qos_t* gq = dds_create_qos();
  if (!q.partitions.empty()) {
    std::vector<const char*> names;
    for (const auto& s : q.partitions) names.push_back(s.c_str());
    dds_qset_partition(gq, static_cast<uint32_t>(names.size()), names.data());
  }
  const dds_entity_t g = publisher ? dds_create_publisher(participant, gq, nullptr)
                                   : dds_create_subscriber(participant, gq, nullptr);
  dds_delete_qos(gq);
  return checked(g, publisher ? "dds_create_publisher" : "dds_create_subscriber");
}
}  // namespace

Participant::Participant(std::uint32_t domain_id)
    : Entity((ensure_loopback_config(),
              checked(dds_create_participant(domain_id, nullptr, nullptr), "dds_create_participant"))) {}

Topic::Topic(const Participant& p, const dds_topic_descriptor_t* d, const std::string& name)
    : Entity(checked(dds_create_topic(p.handle(), d, name.c_str(), nullptr, nullptr),
                     "dds_create_topic")) {}

namespace detail {

dds_entity_t create_writer(const Participant& p, const Topic& t, const QosProfile& q) {
  dds_qos_t* qos = make_qos(q);
  const dds_entity_t pub = with_group(p.handle(), q, true);
  const dds_entity_t w = dds_create_writer(pub, t.handle(), qos, nullptr);
  dds_delete_qos(qos);
  return checked(w, "dds_create_writer");
}

dds_entity_t create_reader(const Participant& p, const Topic& t, const QosProfile& q) {
  dds_qos_t* qos = make_qos(q);
  const dds_entity_t sub = with_group(p.handle(), q, false);
  const dds_entity_t r = dds_create_reader(sub, t.handle(), qos, nullptr);
  dds_delete_qos(qos);
  return checked(r, "dds_create_reader");
}

dds_entity_t repartition_writer(dds_entity_t writer, const Participant& p, const Topic& t, const QosProfile& q) {
  const dds_entity_t pub = dds_get_parent(writer);
  if (pub > 0 && pub != p.handle()) {
    dds_qos_t* gq = dds_create_qos();
    std::vector<const char*> names;
    for (const auto& s : q.partitions) names.push_back(s.c_str());
    dds_qset_partition(gq, static_cast<uint32_t>(names.size()), names.data());
    const dds_return_t rc = dds_set_qos(pub, gq);
    dds_delete_qos(gq);
    if (rc == DDS_RETCODE_OK) return writer;
    if (rc != DDS_RETCODE_UNSUPPORTED && rc != DDS_RETCODE_IMMUTABLE_POLICY) throw DdsError("dds_set_qos(partition)", rc);
    dds_delete(pub);  // deletes the writer with it
  } else if (writer > 0) {
    dds_delete(writer);
  }
  return create_writer(p, t, q);
}

void write(dds_entity_t writer, const void* sample) {
  const dds_return_t rc = dds_write(writer, sample);
  if (rc != DDS_RETCODE_OK) throw DdsError("dds_write", rc);
}

int matched(dds_entity_t entity, bool is_writer) {
  if (is_writer) {
    dds_publication_matched_status_t st;
    const dds_return_t rc = dds_get_publication_matched_status(entity, &st);
    if (rc != DDS_RETCODE_OK) throw DdsError("dds_get_publication_matched_status", rc);
    return static_cast<int>(st.current_count);
  }
  dds_subscription_matched_status_t st;
  const dds_return_t rc = dds_get_subscription_matched_status(entity, &st);
  if (rc != DDS_RETCODE_OK) throw DdsError("dds_get_subscription_matched_status", rc);
  return static_cast<int>(st.current_count);
}

bool wait_for_acks(dds_entity_t writer, double timeout_s) {
  const dds_return_t rc = dds_wait_for_acks(writer, static_cast<dds_duration_t>(timeout_s * 1e9));
  if (rc == DDS_RETCODE_TIMEOUT) return false;
  if (rc != DDS_RETCODE_OK) throw DdsError("dds_wait_for_acks", rc);
  return true;
}

}  // namespace detail

WaitSet::WaitSet(const Participant& p)
    : Entity(checked(dds_create_waitset(p.handle()), "dds_create_waitset")) {}

void WaitSet::attach(dds_entity_t reader) {
  const dds_entity_t cond = checked(
      dds_create_readcondition(reader, DDS_ANY_STATE), "dds_create_readcondition");
  conditions_.emplace_back(cond);
  const dds_return_t rc = dds_waitset_attach(handle(), cond, cond);
  if (rc != DDS_RETCODE_OK) throw DdsError("dds_waitset_attach", rc);
}

bool WaitSet::wait(double timeout_s) {
  const dds_return_t n =
      dds_waitset_wait(handle(), nullptr, 0, static_cast<dds_duration_t>(timeout_s * 1e9));
  if (n < 0) throw DdsError("dds_waitset_wait", n);
  return n > 0;
}

void wait_for_matches(const Participant& p, const std::vector<MatchExpectation>& expected,
                      double timeout_s, const volatile std::atomic<bool>* stop) {
  WaitSet ws(p);
  for (const auto& e : expected) {
    const uint32_t mask = e.is_writer ? DDS_PUBLICATION_MATCHED_STATUS : DDS_SUBSCRIPTION_MATCHED_STATUS;
    dds_return_t rc = dds_set_status_mask(e.entity, mask);
    if (rc != DDS_RETCODE_OK) throw DdsError("dds_set_status_mask", rc);
    rc = dds_waitset_attach(ws.handle(), e.entity, e.entity);
    if (rc != DDS_RETCODE_OK) throw DdsError("dds_waitset_attach", rc);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    std::string missing;
    for (const auto& e : expected) {
      const int m = detail::matched(e.entity, e.is_writer);  // also resets the status trigger
      if (m < e.expected) {
        missing += (missing.empty() ? "" : ", ") + e.name + " (" + std::to_string(m) + "/" +
                   std::to_string(e.expected) + ")";
      }
    }
    if (missing.empty()) break;
    if (stop && stop->load()) throw std::runtime_error("stopped during discovery");
    const double left =
        std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0.0) {
      throw std::runtime_error("discovery incomplete after " + std::to_string(static_cast<int>(timeout_s)) +
                               " s: " + missing);
    }
    const dds_return_t n = dds_waitset_wait(ws.handle(), nullptr, 0,
                                            static_cast<dds_duration_t>(std::min(left, 0.5) * 1e9));
    if (n < 0) throw DdsError("dds_waitset_wait", n);
  }
  for (const auto& e : expected) dds_waitset_detach(ws.handle(), e.entity);
}

std::string to_string(const char* bounded, std::size_t capacity) {
  return std::string(bounded, strnlen(bounded, capacity));
}

void copy_string(char* dst, std::size_t capacity, const std::string& src) {
  const std::size_t n = std::min(src.size(), capacity - 1);
  std::memcpy(dst, src.data(), n);
  dst[n] = '\0';
}

}  // namespace artms::dds
