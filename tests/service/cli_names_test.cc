// The `irfarm` command's names: job states (one a newer coordinator sends that this build does
// not know must not crash `watch` or `cancel`), and the file names `submit --wait -o` derives for
// several jobs (the extension is the last dot of the file name, not of a directory).
#include <gtest/gtest.h>

#include "cli/job_progress.h"
#include "cli/paths.h"

namespace irfarm {
namespace {

TEST(CliNamesTest, StateNames) {
  EXPECT_EQ(StateName(v1::JOB_STATE_RUNNING), "RUNNING");
  EXPECT_EQ(StateName(v1::JOB_STATE_SUCCEEDED), "SUCCEEDED");
  EXPECT_EQ(StateName(v1::JobState(42)), "STATE_42");
  v1::Job job;
  job.set_id("job-1");
  job.set_state(v1::JobState(42));
  EXPECT_NE(ProgressLine(job).find("STATE_42"), std::string::npos) << ProgressLine(job);
}

TEST(CliNamesTest, NumberedPaths) {
  EXPECT_EQ(NumberedPath("out.exr", 2), "out-2.exr");
  EXPECT_EQ(NumberedPath("frames/img", 0), "frames/img-0");
  EXPECT_EQ(NumberedPath("./frames/img", 1), "./frames/img-1");
  EXPECT_EQ(NumberedPath("renders.d/img", 3), "renders.d/img-3");
  EXPECT_EQ(NumberedPath("renders.d/img.exr", 3), "renders.d/img-3.exr");
  EXPECT_EQ(StripExtension("renders.d/img"), "renders.d/img");
  EXPECT_EQ(StripExtension("a/b.c.exr"), "a/b.c");
}

}  // namespace
}  // namespace irfarm
