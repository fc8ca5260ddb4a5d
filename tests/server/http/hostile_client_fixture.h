#pragma once

// A fresh fesbench-server for each test of hostile or broken requests, and
// what every such test must leave behind: the server healthy, a clean exit,
// and no client input having reached the catch-all (it logs every 500 as
// "internal error").

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "server_process.h"

namespace fesbench::testing {

class HostileClientTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>();
    client_ = std::make_unique<httplib::Client>(server_->Client());
    admin_ = server_->admin_token();
  }
  void TearDown() override {
    EXPECT_EQ(Call(*client_, "GET", "/api/v1/health", "").status, 200);
    EXPECT_EQ(server_->Terminate(), 0);
    EXPECT_EQ(server_->Stderr().find("internal error"), std::string::npos) << server_->Stderr();
  }

  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<httplib::Client> client_;
  std::string admin_;
};

}  // namespace fesbench::testing
