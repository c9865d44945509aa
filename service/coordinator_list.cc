// CoordinatorList: address list parsing and finding the coordinator that accepts connections
// (see coordinator_list.h).
#include "service/coordinator_list.h"

#include <algorithm>

namespace irfarm {

absl::StatusOr<std::vector<std::string>> CoordinatorList::Parse(const std::string& list) {
  std::vector<std::string> out;
  size_t start = 0;
  for (;;) {
    const size_t comma = list.find(',', start);
    std::string a =
        list.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const size_t first = a.find_first_not_of(" \t");
    a = first == std::string::npos ? "" : a.substr(first, a.find_last_not_of(" \t") - first + 1);
    if (a.empty())
      return absl::InvalidArgumentError("--coordinator: empty address in '" + list +
                                        "' (expected HOST:PORT[,HOST:PORT...])");
    out.push_back(std::move(a));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

CoordinatorList::CoordinatorList(std::vector<std::string> addresses,
                                 const std::shared_ptr<grpc::ChannelCredentials>& credentials,
                                 const grpc::ChannelArguments& args)
    : addresses_(std::move(addresses)) {
  for (const std::string& a : addresses_)
    channels_.push_back(grpc::CreateCustomChannel(a, credentials, args));
}

std::optional<size_t> CoordinatorList::FindConnected(
    std::chrono::system_clock::time_point deadline) {
  std::vector<grpc_connectivity_state> states(channels_.size());
  for (;;) {
    for (size_t i = 0; i < channels_.size(); ++i) {
      states[i] = channels_[i]->GetState(/*try_to_connect=*/true);
      if (states[i] == GRPC_CHANNEL_READY) return i;
    }
    const auto now = std::chrono::system_clock::now();
    if (now >= deadline) return std::nullopt;
    // Wait for a state change of any channel, in slices of 50 ms, on one completion queue: the
    // waiting is what drives gRPC's connection work (a channel nobody waits on moves on only
    // with gRPC's backup poller, every 5 s, which made a takeover take seconds longer).
    const auto until = std::min(deadline, now + std::chrono::milliseconds(50));
    grpc::CompletionQueue cq;
    for (size_t i = 0; i < channels_.size(); ++i)
      channels_[i]->NotifyOnStateChange(states[i], until, &cq, nullptr);
    void* tag = nullptr;
    bool changed = false;
    for (size_t i = 0; i < channels_.size(); ++i) cq.Next(&tag, &changed);
    cq.Shutdown();
    while (cq.Next(&tag, &changed)) {
    }
  }
}

std::string CoordinatorList::ToString() const {
  std::string s;
  for (const std::string& a : addresses_) s += (s.empty() ? "" : ",") + a;
  return s;
}

}  // namespace irfarm
