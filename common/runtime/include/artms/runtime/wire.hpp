// Plain messages (bus/messages.hpp) to and from their DDS form (idl/artms.idl):
// the only place the two meet. from_wire copies a received sample; write()
// builds the DDS sample around the plain message's buffers and writes it.
#pragma once

#include <vector>

#include "artms.h"
#include "artms/bus/messages.hpp"
#include "artms/dds/dds.hpp"

namespace artms::runtime {

bus::Tick from_wire(const artms_msg_ClockTick& m);
bus::TruthState from_wire(const artms_msg_TruthState& m);
bus::GnssFix from_wire(const artms_msg_GnssFix& m);
bus::CameraFrame from_wire(const artms_msg_CameraFrame& m);
bus::FrameTruth from_wire(const artms_msg_FrameTruth& m);
bus::ImpReport from_wire(const artms_msg_ImpReport& m);
bus::IslBroadcast from_wire(const artms_msg_IslBroadcast& m);
bus::IslOutcome from_wire(const artms_msg_IslOutcome& m);
bus::NavTelemetry from_wire(const artms_msg_NavTelemetry& m);
bus::LinkState from_wire(const artms_msg_LinkState& m);
bus::Event from_wire(const artms_msg_Event& m);
bus::BodAttempt from_wire(const artms_msg_BodAttempt& m);

void write(dds::Writer<artms_msg_TruthState>& w, const bus::TruthState& m);
void write(dds::Writer<artms_msg_GnssFix>& w, const bus::GnssFix& m);
void write(dds::Writer<artms_msg_CameraFrame>& w, const bus::CameraFrame& m);
void write(dds::Writer<artms_msg_FrameTruth>& w, const bus::FrameTruth& m);
void write(dds::Writer<artms_msg_ImpReport>& w, const bus::ImpReport& m);
void write(dds::Writer<artms_msg_IslBroadcast>& w, const bus::IslBroadcast& m);
void write(dds::Writer<artms_msg_IslOutcome>& w, const bus::IslOutcome& m);
void write(dds::Writer<artms_msg_NavTelemetry>& w, const bus::NavTelemetry& m);
void write(dds::Writer<artms_msg_LinkState>& w, const bus::LinkState& m);
void write(dds::Writer<artms_msg_Event>& w, const bus::Event& m);
void write(dds::Writer<artms_msg_BodAttempt>& w, const bus::BodAttempt& m);

// The DDS sample write() sends for a BOD attempt (strings bounded as the IDL
// bounds them, at most bus::kMaxBodSamples curve samples); its curve views
// `curve`, which must outlive it. For the tests.
artms_msg_BodAttempt to_wire(const bus::BodAttempt& b, std::vector<artms_msg_BodSample>& curve);

// Every sample available on a reader now, as plain messages.
template <typename Plain, typename Wire>
std::vector<Plain> take_all(dds::Reader<Wire>& r) {
  std::vector<Plain> out;
  r.take_each([&](const Wire& m) { out.push_back(from_wire(m)); });
  return out;
}

}  // namespace artms::runtime
