#pragma once

// GoogleTest glue for tests/support/postgres_server.h (kept apart so the
// library does not depend on GoogleTest).
//
//   TEST(SubjectsPg, Lists) {
//     fesbench::testing::ScratchDatabase db;
//     FESBENCH_SKIP_WITHOUT_POSTGRES(db);
//     ... db.url() ...
//   }

#include <gtest/gtest.h>

#include "tests/support/postgres_server.h"

/// Ends the test unless `scratch` (a ScratchDatabase) holds a database:
/// skipped, with the reason shown, when the PostgreSQL server is not
/// installed here; failed, with the error, for any other reason (a server
/// that does not start, a database that cannot be created). Use it in the
/// test body or a void SetUp().
#define FESBENCH_SKIP_WITHOUT_POSTGRES(scratch)                       \
  do {                                                               \
    if (!(scratch).ok()) {                                           \
      if ((scratch).skippable()) GTEST_SKIP() << (scratch).skip_reason(); \
      FAIL() << (scratch).skip_reason();                             \
    }                                                                \
  } while (false)
