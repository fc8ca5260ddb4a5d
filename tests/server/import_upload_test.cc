// Imports read within bounds (server/services/import_upload.h,
// docs/SAFETY.md "Uploads"): each upload arrives as a user's file would —
// a zip bomb made here with libarchive, an archive with a stray file, a
// deep or duplicated JSON body, a parameter set with a field the format
// does not have — and is refused naming the place, holding no memory
// afterwards and storing nothing.

#include "server/services/import_upload.h"

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "api/parameter_set_json.h"
#include "server/services/session_archive.h"
#include "storage/database.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"
#include "tests/server/test_archives.h"

namespace fesbench::server::services {
namespace {

using nlohmann::json;
using testing::Entry;
using testing::MakeArchive;

constexpr std::size_t kMiB = std::size_t{1} << 20;
constexpr const char* kRoot = "fesbench-session-7";

// An upload as the front end hands it over: an unlinked file, at offset 0.
class UploadFile {
 public:
  explicit UploadFile(const std::string& bytes) : fd_(::memfd_create("upload", MFD_CLOEXEC)) {
    EXPECT_GE(fd_, 0);
    EXPECT_EQ(::write(fd_, bytes.data(), bytes.size()), static_cast<ssize_t>(bytes.size()));
    ::lseek(fd_, 0, SEEK_SET);
    size_ = bytes.size();
  }
  ~UploadFile() { ::close(fd_); }
  int fd() const { return fd_; }
  std::size_t size() const { return size_; }

 private:
  int fd_;
  std::size_t size_ = 0;
};

// A trial the bench could have recorded (free swing: time and angle).
api::Trial SwingTrial() {
  api::Trial t;
  t.id = 41;
  t.name = "free_swing_passive";
  t.sample_rate_hz = 200.0;
  std::vector<double> time, angle;
  for (int i = 0; i < 400; ++i) {
    time.push_back(i / 200.0);
    angle.push_back(90.0 + 20.0 * std::exp(-0.01 * i) * std::cos(0.2 * i));
  }
  t.SetChannel("t_s", time);
  t.SetChannel("angle_deg", angle);
  return t;
}

// The files of an export holding trial 41 and parameter set 5 identified from it.
api::FileMap ExportFiles() {
  api::FileMap files;
  api::AddBidsTrial(SwingTrial(), {"S01", "7", "right", 41}, files);
  files["README.md"] = "# fesbench session 7\n";
  files["dataset_description.json"] = R"({"Name": "fesbench session 7", "BIDSVersion": "1.11.0"})";
  model::ParameterSet params = model::ExampleParameterSet();
  params.provenance.trial_ids = {41};
  params.provenance.active_trial_id.reset();
  // The derivative's prediction of set 5 on trial 41, its errors and an
  // EMG copy for other tools: unpacked with the rest, not imported.
  files["derivatives/fesbench/predictions.tsv"] =
      "prediction_id\tparameter_set_id\ttrial_id\tcreated_at\tchannel\tunit\te_rms\te_abs\n"
      "9\t5\t41\t2026-11-25T10:00:01.000000Z\tangle_deg\tdeg\t2.5\t6\n";
  files["derivatives/fesbench/predictions/prediction-9.json"] = R"({"id": 9})";
  files["derivatives/fesbench/evaluations.json"] = "[]";
  files
      ["derivatives/fesbench/sub-S01/ses-7/emg/"
       "sub-S01_ses-7_task-freeSwingPassive_run-41_emg.edf"] = std::string(256, ' ');
  files["derivatives/fesbench/parameter_sets/paramset-5.json"] = json{
      {"id", 5},
      {"version", 1},
      {"created_at", "2026-11-25T10:00:00.000000Z"},
      {"supersedes_id", nullptr},
      {"parameter_set", api::ParameterSetToJson(params)}}.dump(2);
  return files;
}

std::vector<Entry> Entries(const api::FileMap& files, const std::string& root = kRoot) {
  std::vector<Entry> entries;
  for (const auto& [path, content] : files) entries.push_back({root + "/" + path, content});
  return entries;
}

const std::string kMotion =
    std::string(kRoot) +
    "/sub-S01/ses-7/motion/"
    "sub-S01_ses-7_task-freeSwingPassive_tracksys-kneebench_run-41_motion.tsv";

api::Result<UnpackedArchive> Unpack(const std::string& bytes, MemoryBudget& budget,
                                    ArchiveFormat format = ArchiveFormat::kZip) {
  UploadFile file(bytes);
  return UnpackArchive(file.fd(), format, budget);
}

TEST(UnpackArchiveTest, TheExportLayoutUnpacksUnderItsRootInBothFormats) {
  MemoryBudget budget(192 * kMiB);
  for (const ArchiveFormat format : {ArchiveFormat::kZip, ArchiveFormat::kTarGz}) {
    auto unpacked = Unpack(MakeArchive(Entries(ExportFiles()), format), budget, format);
    ASSERT_TRUE(unpacked.ok()) << unpacked.status().ToString();
    EXPECT_EQ(unpacked->files, ExportFiles());
    EXPECT_GT(budget.in_use(), 0u) << "the files are held within the budget";
  }
  EXPECT_EQ(budget.in_use(), 0u) << "given back with the files";
}

TEST(UnpackArchiveTest, AZipBombIsRefusedNamingTheEntryAndTheLimit) {
  MemoryBudget budget(192 * kMiB);
  // 256 MiB of zeros compress to a quarter of a MiB.
  const std::string bomb = MakeArchive({{kMotion, "", 256}}, ArchiveFormat::kZip);
  EXPECT_LT(bomb.size(), kMiB);
  auto unpacked = Unpack(bomb, budget);
  ASSERT_FALSE(unpacked.ok());
  EXPECT_EQ(unpacked.status().code(), api::ErrorCode::kPayloadTooLarge);
  EXPECT_NE(unpacked.status().message().find(kMotion), std::string::npos)
      << unpacked.status().message();
  EXPECT_NE(unpacked.status().message().find("128 MiB"), std::string::npos)
      << unpacked.status().message();
  // The same zeros as a small file of the layout (a sidecar): its own limit.
  const std::string sidecar = std::string(kRoot) + "/participants.tsv";
  auto small =
      Unpack(MakeArchive({{sidecar, "", 8}}, ArchiveFormat::kTarGz), budget, ArchiveFormat::kTarGz);
  ASSERT_FALSE(small.ok());
  EXPECT_EQ(small.status().code(), api::ErrorCode::kPayloadTooLarge);
  EXPECT_NE(small.status().message().find(sidecar + "' unpacks beyond 1 MiB"), std::string::npos)
      << small.status().message();
  EXPECT_EQ(budget.in_use(), 0u);
}

TEST(UnpackArchiveTest, EntriesOutsideTheLayoutAreRefusedByName) {
  MemoryBudget budget(192 * kMiB);
  const auto refused = [&](std::vector<Entry> entries, const std::string& named) {
    auto unpacked = Unpack(MakeArchive(entries, ArchiveFormat::kZip), budget);
    ASSERT_FALSE(unpacked.ok()) << named;
    EXPECT_EQ(unpacked.status().code(), api::ErrorCode::kInvalidArgument);
    EXPECT_NE(unpacked.status().message().find("'" + named + "'"), std::string::npos)
        << unpacked.status().message();
  };
  // One stray file beside the root, inside it, or among the trials.
  std::vector<Entry> entries = Entries(ExportFiles());
  entries.push_back({"notes.txt", "remember the electrodes"});
  refused(entries, "notes.txt");
  entries = Entries(ExportFiles());
  entries.push_back({std::string(kRoot) + "/.DS_Store", "x"});
  refused(entries, std::string(kRoot) + "/.DS_Store");
  entries = Entries(ExportFiles());
  entries.push_back({std::string(kRoot) + "/sub-S01/ses-7/motion/raw.csv", "t_s\n0\n"});
  refused(entries, std::string(kRoot) + "/sub-S01/ses-7/motion/raw.csv");
  // EMG outside the derivative (the layout keeps it there), a stray file
  // inside the derivative's trial folders, a prediction not by number.
  for (const std::string path :
       {"/sub-S01/ses-7/emg/sub-S01_ses-7_task-freeSwingPassive_run-41_emg.tsv",
        "/derivatives/fesbench/sub-S01/ses-7/motion/notes.txt",
        "/derivatives/fesbench/predictions/prediction-latest.json"}) {
    entries = Entries(ExportFiles());
    entries.push_back({std::string(kRoot) + path, "x"});
    refused(entries, std::string(kRoot) + path);
  }
  // A root that is not an export's, and two roots.
  refused(Entries(ExportFiles(), "my-session"), "my-session/README.md");
  entries = Entries(ExportFiles());
  entries.push_back({"fesbench-session-8/README.md", "x"});
  refused(entries, "fesbench-session-8/README.md");
  // A path twice (zip allows it; which one would count?).
  entries = Entries(ExportFiles());
  entries.push_back({std::string(kRoot) + "/README.md", "the other readme"});
  refused(entries, std::string(kRoot) + "/README.md");
  EXPECT_EQ(budget.in_use(), 0u);
}

TEST(UnpackArchiveTest, ABodyNotInItsDeclaredFormatIsRefused) {
  MemoryBudget budget(192 * kMiB);
  const std::string zip = MakeArchive(Entries(ExportFiles()), ArchiveFormat::kZip);
  auto as_gzip = Unpack(zip, budget, ArchiveFormat::kTarGz);
  ASSERT_FALSE(as_gzip.ok());
  EXPECT_NE(as_gzip.status().message().find("not a tar.gz"), std::string::npos)
      << as_gzip.status().message();
  auto garbage = Unpack("not an archive", budget);
  ASSERT_FALSE(garbage.ok());
  EXPECT_NE(garbage.status().message().find("not a zip"), std::string::npos)
      << garbage.status().message();
}

TEST(UnpackArchiveTest, TheBudgetIsSharedAndSaysWhenItIsSpent) {
  const std::string zip = MakeArchive(Entries(ExportFiles()), ArchiveFormat::kZip);
  MemoryBudget budget(4 * kMiB);
  {
    // Other uploads hold nearly all of it: retry later.
    auto others = budget.Reserve(4 * kMiB - 1000);
    ASSERT_TRUE(others.ok());
    auto busy = Unpack(zip, budget);
    ASSERT_FALSE(busy.ok());
    EXPECT_EQ(busy.status().code(), api::ErrorCode::kUnavailable);
    EXPECT_NE(busy.status().message().find("busy with other uploads"), std::string::npos);
    EXPECT_EQ(budget.in_use(), 4 * kMiB - 1000) << "the refused archive holds nothing";
  }
  auto alone = Unpack(zip, budget);
  EXPECT_TRUE(alone.ok()) << alone.status().ToString();
  // An archive whose tables would need more than the whole budget: too large.
  MemoryBudget tiny(16 << 10);
  auto too_large = Unpack(zip, tiny);
  ASSERT_FALSE(too_large.ok());
  EXPECT_EQ(too_large.status().code(), api::ErrorCode::kPayloadTooLarge);
  EXPECT_NE(too_large.status().message().find("for imports"), std::string::npos)
      << too_large.status().message();
}

TEST(MemoryBudgetTest, ReservationsGrowShrinkAndGiveBack) {
  MemoryBudget budget(100);
  auto a = budget.Reserve(60);
  ASSERT_TRUE(a.ok());
  auto b = budget.Reserve(50);
  EXPECT_FALSE(b.ok());
  EXPECT_EQ(b.status().code(), api::ErrorCode::kUnavailable);
  EXPECT_TRUE(a->Resize(20).ok());
  auto c = budget.Reserve(80);
  ASSERT_TRUE(c.ok());
  EXPECT_FALSE(a->Resize(21).ok());
  EXPECT_EQ(a->bytes(), 20u) << "a refused growth keeps what it held";
  MemoryBudget::Reservation moved = std::move(*c);
  EXPECT_EQ(budget.in_use(), 100u);
  moved = MemoryBudget::Reservation();
  EXPECT_EQ(budget.in_use(), 20u);
}

// --- Recordings ----------------------------------------------------------------

api::Result<RecordingUpload> ReadBody(const std::string& body, MemoryBudget& budget) {
  UploadFile file(body);
  return ReadRecordingUpload(file.fd(), file.size(), budget);
}

const std::string kCsv = "t_s,angle_deg\n0,90\n0.005,91\n0.01,92\n";

TEST(ReadRecordingUploadTest, ReadsSpecAndDataWithinTheBudget) {
  MemoryBudget budget(192 * kMiB);
  auto upload =
      ReadBody(json{{"spec", {{"kind", "free_swing_passive"}}}, {"data", kCsv}}.dump(), budget);
  ASSERT_TRUE(upload.ok()) << upload.status().ToString();
  EXPECT_EQ(upload->spec.kind, "free_swing_passive");
  EXPECT_EQ(upload->data, kCsv);
  EXPECT_GE(upload->memory.bytes(), kCsv.size());
}

TEST(ReadRecordingUploadTest, RefusesDeepDuplicatedAndUnknownNamingThePlace) {
  MemoryBudget budget(192 * kMiB);
  const auto field_of = [&](const std::string& body) {
    auto upload = ReadBody(body, budget);
    EXPECT_FALSE(upload.ok()) << body.substr(0, 200);
    if (upload.ok()) return std::string("(accepted)");
    EXPECT_EQ(upload.status().code(), api::ErrorCode::kInvalidArgument);
    return upload.status().field() + " | " + upload.status().message();
  };
  // Ten million levels: refused before the parser recurses.
  std::string deep(10'000'000, '[');
  deep.append(10'000'000, ']');
  EXPECT_NE(field_of(R"({"spec": {"kind": "free_swing_passive"}, "data": )" + deep + "}")
                .find("nested deeper than 32"),
            std::string::npos);
  deep = {};
  const std::string spec = R"("spec": {"kind": "free_swing_passive"})";
  EXPECT_EQ(field_of("{" + spec + R"(, "data": "x", "data": "t_s\n0\n"})").rfind("data | ", 0), 0u);
  EXPECT_EQ(field_of(R"({"spec": {"kind": "free_swing_passive", "kind": "walking"}, "data": "x"})")
                .rfind("spec.kind | ", 0),
            0u);
  EXPECT_EQ(
      field_of(
          R"({"spec": {"kind": "free_swing_passive", "columns": [{"column": "a", "channel": "angle_deg", "channel": "torque_nm"}]}, "data": "x"})")
          .rfind("spec.columns[0].channel | ", 0),
      0u);
  EXPECT_EQ(field_of("{" + spec + R"(, "data": "x", "comment": "from the lab"})")
                .rfind("comment | unknown field", 0),
            0u);
  EXPECT_EQ(field_of(R"({"spec": {"kind": "free_swing_passive", "colour": 1}, "data": "x"})")
                .rfind("spec.colour | unknown field", 0),
            0u);
  EXPECT_EQ(field_of("{" + spec + R"(, "data": 5})").rfind("data | ", 0), 0u);
  EXPECT_EQ(budget.in_use(), 0u);
}

TEST(ReadRecordingUploadTest, ARecordingBeyondTheBudgetIsTooLargeAndABusyOneWaits) {
  const std::string body = json{{"spec", {{"kind", "free_swing_passive"}}}, {"data", kCsv}}.dump();
  MemoryBudget tiny(1 << 20);
  auto too_large = ReadBody(body, tiny);
  ASSERT_FALSE(too_large.ok());
  EXPECT_EQ(too_large.status().code(), api::ErrorCode::kPayloadTooLarge);
  MemoryBudget budget(8 * kMiB);
  auto others = budget.Reserve(7 * kMiB);
  ASSERT_TRUE(others.ok());
  auto busy = ReadBody(body, budget);
  ASSERT_FALSE(busy.ok());
  EXPECT_EQ(busy.status().code(), api::ErrorCode::kUnavailable);
}

// --- Importing an archive: all or nothing -------------------------------------

class ImportArchiveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = std::filesystem::temp_directory_path() /
           ("fesbench_import_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    storage::DatabaseOptions o;
    o.path = (dir_ / "fesbench.db").string();
    auto db = storage::Database::Open(o);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    db_ = std::move(*db);
    storage::SubjectRepository subjects(*db_);
    auto subject = subjects.Create("IMP-01", storage::SubjectDetails{});
    ASSERT_TRUE(subject.ok());
    auto leg = subjects.AddLeg(subject->id, storage::Side::kRight);
    ASSERT_TRUE(leg.ok());
    storage::SessionDetails details;
    details.date = "2026-11-25";
    auto session = storage::SessionRepository(*db_).Create(subject->id, leg->id, details);
    ASSERT_TRUE(session.ok());
    session_ = *session;
  }
  void TearDown() override {
    db_.reset();
    std::filesystem::remove_all(dir_);
  }

  // Trials and parameter sets stored for the session.
  std::pair<std::size_t, std::size_t> Stored() {
    auto trials = storage::TrialRepository(*db_).ListForSession(session_.id);
    auto sets = storage::ParameterSetRepository(*db_).IdsForSession(session_.id);
    EXPECT_TRUE(trials.ok() && sets.ok());
    return {trials.ok() ? trials->size() : 999, sets.ok() ? sets->size() : 999};
  }

  api::Status Import(const api::FileMap& files) {
    auto r = ImportArchive(*db_, session_.id, files, "test.zip", "tester");
    return r.ok() ? api::Status::Ok() : r.status();
  }

  std::filesystem::path dir_;
  std::unique_ptr<storage::Database> db_;
  storage::Session session_;
};

TEST_F(ImportArchiveTest, ImportsTheTrialAndItsParameterSet) {
  ASSERT_TRUE(Import(ExportFiles()).ok());
  EXPECT_EQ(Stored(), std::make_pair(std::size_t{1}, std::size_t{1}));
}

TEST_F(ImportArchiveTest, AParameterSetWithAnUnknownOrDuplicatedFieldStoresNothing) {
  const std::string path = "derivatives/fesbench/parameter_sets/paramset-5.json";
  const auto refused = [&](const std::function<void(json&)>& edit, const std::string& field) {
    api::FileMap files = ExportFiles();
    json j = json::parse(files[path]);
    edit(j);
    files[path] = j.dump();
    const api::Status s = Import(files);
    EXPECT_EQ(s.code(), api::ErrorCode::kInvalidArgument) << field;
    EXPECT_NE(s.message().find(path), std::string::npos) << s.message();
    EXPECT_EQ(s.field(), field) << s.ToString();
    EXPECT_EQ(Stored(), std::make_pair(std::size_t{0}, std::size_t{0})) << field;
  };
  refused([](json& j) { j["colour"] = "blue"; }, "colour");
  refused([](json& j) { j["parameter_set"]["passive"]["stiffness"] = 1; },
          "parameter_set.passive.stiffness");
  refused([](json& j) { j["created_at"] = "yesterday"; }, "created_at");
  refused([](json& j) { j.erase("id"); }, "id");
  refused([](json& j) { j["supersedes_id"] = "4"; }, "supersedes_id");
  // The same key twice, which a JSON object cannot hold: refused, not "last wins".
  api::FileMap files = ExportFiles();
  files[path].insert(1, R"("id": 6, )");
  const api::Status s = Import(files);
  EXPECT_EQ(s.field(), "id") << s.ToString();
  EXPECT_NE(s.message().find("duplicate"), std::string::npos) << s.message();
  EXPECT_EQ(Stored(), std::make_pair(std::size_t{0}, std::size_t{0}));
}

}  // namespace
}  // namespace fesbench::server::services
