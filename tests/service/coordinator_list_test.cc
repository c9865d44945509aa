// CoordinatorList: parsing `--coordinator a,b` and finding the address that accepts
// connections (the active coordinator; standbys do not listen), with real gRPC servers on
// loopback.
#include "service/coordinator_list.h"

#include <gtest/gtest.h>

#include "irfarm/v1/worker.grpc.pb.h"
#include "tests/service/redis_server.h"

namespace irfarm {
namespace {

TEST(CoordinatorListTest, ParsesCommaSeparatedAddresses) {
  EXPECT_EQ(*CoordinatorList::Parse("127.0.0.1:1"), std::vector<std::string>{"127.0.0.1:1"});
  EXPECT_EQ(*CoordinatorList::Parse("a:1, b:2 ,c:3"),
            (std::vector<std::string>{"a:1", "b:2", "c:3"}));
  EXPECT_TRUE(absl::IsInvalidArgument(CoordinatorList::Parse("").status()));
  EXPECT_TRUE(absl::IsInvalidArgument(CoordinatorList::Parse("a:1,,b:2").status()));
  EXPECT_TRUE(absl::IsInvalidArgument(CoordinatorList::Parse("a:1,").status()));
}

// A server on a free port (any service: only the connection matters).
std::unique_ptr<grpc::Server> Listen(int port, v1::WorkerService::Service* service) {
  grpc::ServerBuilder builder;
  builder.AddListeningPort("127.0.0.1:" + std::to_string(port), grpc::InsecureServerCredentials());
  builder.RegisterService(service);
  return builder.BuildAndStart();
}

TEST(CoordinatorListTest, FindsTheAddressThatListensAndTheNextOneAfterIt) {
  const int first = FreePort(), second = FreePort();
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
  CoordinatorList list(*CoordinatorList::Parse("127.0.0.1:" + std::to_string(first) +
                                               ",127.0.0.1:" + std::to_string(second)),
                       grpc::InsecureChannelCredentials(), args);
  ASSERT_EQ(list.size(), 2u);
  const auto soon = [] { return std::chrono::system_clock::now() + std::chrono::seconds(3); };
  // Nobody listens: none within the deadline.
  EXPECT_FALSE(
      list.FindConnected(std::chrono::system_clock::now() + std::chrono::milliseconds(300)));
  v1::WorkerService::Service service;
  std::unique_ptr<grpc::Server> b = Listen(second, &service);
  ASSERT_TRUE(b);
  EXPECT_EQ(list.FindConnected(soon()), std::optional<size_t>(1));
  // The second goes away and the first comes up (a standby took over).
  b->Shutdown(std::chrono::system_clock::now());
  b.reset();
  // The channel reports READY until it has seen the connection close (a client learns it from a
  // failed call or this state change); until then FindConnected rightly still returns 1. This
  // once failed the test when the check below came first.
  const auto seen_gone = soon();
  while (list.channel(1)->GetState(false) == GRPC_CHANNEL_READY &&
         std::chrono::system_clock::now() < seen_gone)
    list.channel(1)->WaitForStateChange(GRPC_CHANNEL_READY, seen_gone);
  ASSERT_NE(list.channel(1)->GetState(false), GRPC_CHANNEL_READY);
  std::unique_ptr<grpc::Server> a = Listen(first, &service);
  ASSERT_TRUE(a);
  EXPECT_EQ(list.FindConnected(soon()), std::optional<size_t>(0));
  EXPECT_EQ(list.ToString(),
            "127.0.0.1:" + std::to_string(first) + ",127.0.0.1:" + std::to_string(second));
}

}  // namespace
}  // namespace irfarm
