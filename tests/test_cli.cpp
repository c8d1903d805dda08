// The cellphys command, run as a process: every built-in scene for a few steps with sane
// statistics; the trajectory CSV; the default world with no scene; `scenes`; usage errors; and
// broken scene files (each kind of error, truncated, not JSON, 100 MB of junk) refused with
// the file, the JSON path and exit code 2, leaving no output file behind (and an existing
// one untouched).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

const std::string kExe = CELLPHYS_EXE;
const std::string kScenes = CELLPHYS_SCENES_DIR;

struct Result {
  int code = -1;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void spit(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// A fresh directory per test, removed afterwards.
class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("cellphys_cli_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs the command; with `env` false, without CELLPHYS_SCENES (the built-in lookup alone).
  Result run(const std::vector<std::string>& args, bool env = true) const {
    std::string cmd = (env ? "CELLPHYS_SCENES=" + shell_quote(kScenes) : std::string("env -u CELLPHYS_SCENES")) + " " +
                      shell_quote(kExe);
    for (const std::string& a : args) cmd += " " + shell_quote(a);
    const fs::path out = dir_ / ".stdout", err = dir_ / ".stderr";
    cmd += " >" + shell_quote(out.string()) + " 2>" + shell_quote(err.string()) + " </dev/null";
    const int status = std::system(cmd.c_str());
    Result r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    fs::remove(out);
    fs::remove(err);
    return r;
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  // Files in the test directory (what a run left behind).
  std::vector<std::string> files() const {
    std::vector<std::string> f;
    for (const auto& e : fs::directory_iterator(dir_)) f.push_back(e.path().filename().string());
    std::sort(f.begin(), f.end());
    return f;
  }

  fs::path dir_;
};

std::vector<std::string> builtin_names() {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(kScenes))
    if (e.path().extension() == ".json") names.push_back(e.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

size_t scene_bodies(const std::string& name) {
  const json j = json::parse(slurp(fs::path(kScenes) / (name + ".json")));
  return j.contains("bodies") ? j["bodies"].size() : 0;
}

const char* const kStatsKeys[] = {"steps", "sim_time_s", "wall_s", "ms_per_step_median", "bodies", "active_bodies",
                                  "sleeping_bodies", "islands", "contacts", "solver_iterations_mean",
                                  "step_halvings", "failed_islands", "local_store_peak_bytes", "decoupled_islands",
                                  "kinetic_energy_initial", "kinetic_energy_final"};

TEST_F(Cli, EveryBuiltinSceneRunsWithSaneStatistics) {
  const std::vector<std::string> names = builtin_names();
  ASSERT_GE(names.size(), 9u);
  for (const std::string& name : names) {
    SCOPED_TRACE(name);
    const std::string stats = path(name + ".stats.json");
    const Result r = run({"run", name, "--steps", "5", "--stats", stats});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find(name), std::string::npos) << r.out;
    const json j = json::parse(slurp(stats));
    for (const char* k : kStatsKeys) {
      ASSERT_TRUE(j.contains(k)) << k;
      ASSERT_TRUE(j[k].is_number()) << k << " = " << j[k].dump();
      EXPECT_TRUE(std::isfinite(j[k].get<double>())) << k;
      EXPECT_GE(j[k].get<double>(), 0.0) << k;
    }
    EXPECT_EQ(j["steps"].get<int>(), 5);
    EXPECT_EQ(j["bodies"].get<size_t>(), scene_bodies(name));
    EXPECT_LE(j["active_bodies"].get<size_t>() + j["sleeping_bodies"].get<size_t>(), scene_bodies(name));
    EXPECT_EQ(j["failed_islands"].get<int>(), 0);
    EXPECT_NEAR(j["sim_time_s"].get<double>(), 5 * j["dt"].get<double>(), 1e-12);
  }
}

// Each stage of the step is timed under its name (docs/scene-format.md), and the stages are
// disjoint parts of the step, so their times add up to at most the step's.
TEST_F(Cli, StatsGiveEachStageOfTheStepItsTimeUnderItsName) {
  const std::string stats = path("stages.json");
  const Result r = run({"run", "pile65", "--steps", "20", "--stats", stats});
  ASSERT_EQ(r.code, 0) << r.err;
  const json stages = json::parse(slurp(stats))["stage_ms_mean"];
  const std::vector<std::string> names = {"broad", "mid",  "narrow",    "wake",   "push",  "islands",
                                          "decouple", "pack", "integrate", "unpack", "sleep", "events", "total"};
  ASSERT_EQ(stages.size(), names.size()) << stages.dump();
  double parts = 0;
  for (const std::string& n : names) {
    ASSERT_TRUE(stages.contains(n) && stages[n].is_number()) << n << " in " << stages.dump();
    const double ms = stages[n].get<double>();
    EXPECT_TRUE(std::isfinite(ms) && ms >= 0.0) << n << " = " << ms;
    if (n != "total") parts += ms;
  }
  EXPECT_GT(stages["integrate"].get<double>(), 0.0);  // pile65 is awake and integrated every step
  EXPECT_LE(parts, stages["total"].get<double>() * (1 + 1e-9)) << stages.dump();
}

TEST_F(Cli, DurationEveryAndTheTrajectoryCsv) {
  const std::string csv = path("traj.csv"), stats = path("stats.json");
  // pendulum: dt 1/120; 0.1 s is 12 steps; every 5th step plus step 0: steps 0, 5, 10
  const Result r = run({"run", "pendulum", "--duration", "0.1", "--out", csv, "--every", "5", "--stats", stats});
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(slurp(stats));
  EXPECT_EQ(j["steps"].get<int>(), 12);
  std::istringstream in(slurp(csv));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "step,t,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz");
  std::vector<int> steps;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ls(line);
    for (std::string c; std::getline(ls, c, ',');) cells.push_back(c);
    ASSERT_EQ(cells.size(), 16u) << line;
    EXPECT_EQ(cells[2], "bob");
    for (size_t k = 3; k < 16; ++k) EXPECT_TRUE(std::isfinite(std::stod(cells[k]))) << line;
    steps.push_back(std::stoi(cells[0]));
  }
  EXPECT_EQ(steps, (std::vector<int>{0, 5, 10}));
  EXPECT_EQ(files(), (std::vector<std::string>{"stats.json", "traj.csv"})) << "no temporaries left";
}

// --events: a ball dropped through a trigger onto the ground: the trigger's entry and exit, then
// the landing's touch with the closed form's speed and an impulse; rows parse, names are the
// scene's.
TEST_F(Cli, TheEventsCsvHasTheLandingAndTheTrigger) {
  const std::string scene = path("drop.json"), csv = path("events.csv");
  spit(scene, R"({"shapes": [{"name": "floor", "type": "plane", "normal": [0, 0, 1]},
                          {"name": "ball", "type": "sphere", "radius": 0.2},
                          {"name": "zone", "type": "box", "half_extents": [1, 1, 0.25]}],
               "bodies": [{"id": "ground", "shape": "floor"},
                          {"id": "trigger", "shape": "zone", "static": true, "sensor": true, "position": [0, 0, 1]},
                          {"id": "ball", "shape": "ball", "mass": 2, "position": [0, 0, 2.2]}]})");
  const Result r = run({"run", scene, "--duration", "1.5", "--events", csv});
  ASSERT_EQ(r.code, 0) << r.err;
  std::istringstream in(slurp(csv));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "step,t,event,a,b,px,py,pz,nx,ny,nz,approach_speed,impulse");
  std::vector<std::string> kinds;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ls(line + ",");  // a trailing empty cell is a cell
    for (std::string c; std::getline(ls, c, ',');) cells.push_back(c);
    ASSERT_EQ(cells.size(), 13u) << line;
    kinds.push_back(cells[2] + " " + cells[3] + " " + cells[4]);
    if (cells[2] == "touch_begin") {
      EXPECT_NEAR(std::stod(cells[11]), std::sqrt(2 * 9.81 * 2.0), 9.81 / 60 + 0.1) << line;  // fell 2 m
      EXPECT_GT(std::stod(cells[12]), 0.0) << line;
      EXPECT_NEAR(std::stod(cells[10]), 1.0, 1e-5) << line;  // from the ground up to the ball
    }
  }
  const std::vector<std::string> want = {"sensor_begin trigger ball", "sensor_end trigger ball", "touch_begin ground ball"};
  ASSERT_GE(kinds.size(), 3u);
  EXPECT_EQ(want, std::vector<std::string>(kinds.begin(), kinds.begin() + 3));
  EXPECT_EQ(run({"run", scene, "--events", csv, "--out", csv}).code, 2) << "one file for two outputs is refused";
}

TEST_F(Cli, OverridesReachTheWorld) {
  const std::string stats = path("s.json");
  const Result r = run({"run", "spin", "--steps", "3", "--dt", "0.01", "--integrator", "rk4", "--solver", "direct",
                        "--tolerance", "1e-6", "--workers", "2", "--stats", stats});
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(slurp(stats));
  EXPECT_EQ(j["integrator"], "rk4");
  EXPECT_EQ(j["solver"], "direct");
  EXPECT_EQ(j["workers"], 2);
  EXPECT_NEAR(j["dt"].get<double>(), 0.01, 1e-9);
}

TEST_F(Cli, NoSceneRunsTheDefaultWorld) {
  const Result r = run({"--steps", "2"}, /*env=*/false);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("world1000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("1001"), std::string::npos) << r.out;
  const Result s = run({"run", "--steps", "1"});
  ASSERT_EQ(s.code, 0) << s.err;
  EXPECT_NE(s.out.find("world1000"), std::string::npos);
  EXPECT_TRUE(s.err.empty()) << "no progress bar when stderr is not a terminal: " << s.err;
}

TEST_F(Cli, ScenesListsEveryBuiltinSceneWithItsDescription) {
  const Result r = run({"scenes"});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const std::string& name : builtin_names()) {
    const size_t at = r.out.find(name + " ");
    ASSERT_NE(at, std::string::npos) << name;
    const std::string line = r.out.substr(at, r.out.find('\n', at) - at);
    EXPECT_GT(line.size(), name.size() + 20) << "a description follows: " << line;
  }
  EXPECT_EQ(r.out.rfind("world1000", 0), 0u) << "the default comes first";
}

TEST_F(Cli, HelpAndUsageErrors) {
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"--help"}, {"help"}, {"run", "--help"}, {"scenes", "--help"}, {"kernel-demo", "--help"}}) {
    const Result r = run(args);
    EXPECT_EQ(r.code, 0) << args.back();
    EXPECT_NE(r.out.find("usage: cellphys"), std::string::npos) << r.out;
  }
  struct Bad {
    std::vector<std::string> args;
    const char* message;
  };
  for (const Bad& b : {Bad{{"run", "--bogus"}, "unknown option '--bogus'"},
                       Bad{{"run", "pendulum", "--steps", "3", "--duration", "1"}, "not both"},
                       Bad{{"run", "pendulum", "--steps", "-3"}, "--steps"},
                       Bad{{"run", "pendulum", "--dt", "abc"}, "--dt needs a positive number"},
                       Bad{{"run", "pendulum", "--every", "0"}, "--every"},
                       Bad{{"run", "pendulum", "--integrator", "verlet"}, "unknown integrator 'verlet'"},
                       Bad{{"run", "pendulum", "--solver", "gmres"}, "unknown solver 'gmres'"},
                       Bad{{"run", "pendulum", "--workers", "0"}, "--workers"},
                       Bad{{"run", "no_such_scene"}, "unknown scene 'no_such_scene'"},
                       Bad{{"run", "a", "b"}, "more than one scene"},
                       Bad{{"run", "pendulum", "--steps"}, "--steps needs a value"},
                       Bad{{"run", "pendulum", "--out", "same.csv", "--stats", "./same.csv"},
                           "--out and --stats name the same file"},
                       Bad{{"frobnicate"}, "unknown command 'frobnicate'"}}) {
    const Result r = run(b.args);
    EXPECT_EQ(r.code, 2) << b.message;
    EXPECT_NE(r.err.find(b.message), std::string::npos) << r.err;
  }
}

TEST_F(Cli, KernelDemoStillRuns) {
  const Result r = run({"kernel-demo", "--steps", "3"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("reference group"), std::string::npos) << r.out;
}

// A scene file that must be refused: exit 2, stderr names the file and the JSON path, and
// neither output file exists afterwards (an existing one keeps its content).
void expect_refused(const Cli& t, const Result& r, const std::string& file, const std::string& json_path,
                    const std::string& reason) {
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find(file + ": "), std::string::npos) << r.err;
  if (!json_path.empty()) EXPECT_NE(r.err.find(": " + json_path + ": "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(reason), std::string::npos) << r.err;
  (void)t;
}

TEST_F(Cli, BrokenScenesAreRefusedAndLeaveNoOutput) {
  const std::string shapes = R"("shapes": [{"name": "s", "type": "sphere", "radius": 0.1}])";
  const std::string two = R"({"id": "a", "shape": "s", "mass": 1}, {"id": "b", "shape": "s", "mass": 1, "position": [1, 0, 0]})";
  auto scene = [&](const std::string& bodies, const std::string& rest = "") {
    return "{" + shapes + R"(, "bodies": [)" + bodies + "]" + rest + "}";
  };
  struct Case {
    const char* what;
    std::string text, path, reason;
  };
  const std::string good = scene(two);
  const std::vector<Case> cases = {
      {"unknown field", scene(two + R"(, {"id": "c", "shape": "s", "mass": 1, "colour": "red"})"), "bodies[2].colour",
       "unknown field"},
      {"wrong type", scene(R"({"id": "a", "shape": "s", "mass": 1, "position": [0, "up", 0]})"),
       "bodies[0].position[1]", "expected a number"},
      {"missing body", scene(two, R"(, "forces": [{"type": "spring", "a": "a", "b": "c"}])"), "forces[0].b",
       "no body with id 'c'"},
      {"unknown shape", scene(R"({"id": "a", "shape": "cube", "mass": 1})"), "bodies[0].shape", "unknown shape"},
      {"unknown force type", scene(two, R"(, "forces": [{"type": "magnet", "a": "a", "b": "b"}])"), "forces[0].type",
       "unknown force type"},
      {"unknown force parameter", scene(two, R"(, "forces": [{"type": "point_to_point", "a": "a", "b": "b", "rest_length": 1}])"),
       "forces[0].rest_length", "unknown parameter"},
      {"non-finite number", scene(R"({"id": "a", "shape": "s", "mass": 1, "velocity": [1e400, 0, 0]})"),
       "bodies[0].velocity[0]", "not finite"},
      {"bad shape", R"({"shapes": [{"name": "s", "type": "box", "half_extents": [1, 0, 1]}]})", "shapes[0]", "box"},
      {"truncated", good.substr(0, good.size() / 2), "", "not valid JSON"},
      {"not JSON", "<scene><body/></scene>", "", "not valid JSON"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const std::string file = path("broken.json");
    spit(file, c.text);
    // no output files before: none after
    Result r = run({"run", file, "--steps", "3", "--out", path("t.csv"), "--stats", path("s.json")});
    expect_refused(*this, r, file, c.path, c.reason);
    EXPECT_EQ(files(), std::vector<std::string>{"broken.json"});
    // an existing output file is left as it was
    spit(path("t.csv"), "previous\n");
    r = run({"run", file, "--steps", "3", "--out", path("t.csv")});
    expect_refused(*this, r, file, c.path, c.reason);
    EXPECT_EQ(slurp(path("t.csv")), "previous\n");
    EXPECT_EQ(files(), (std::vector<std::string>{"broken.json", "t.csv"}));
    fs::remove(path("t.csv"));
  }
  // and the good one runs
  spit(path("good.json"), good);
  const Result ok = run({"run", path("good.json"), "--steps", "2", "--out", path("t.csv")});
  EXPECT_EQ(ok.code, 0) << ok.err;
}

TEST_F(Cli, HundredMegabytesOfJunkIsRefusedQuickly) {
  const std::string file = path("junk.json");
  {
    std::ofstream out(file, std::ios::binary);
    std::mt19937 g(5);
    std::string block(1 << 20, '\0');
    for (int mb = 0; mb < 100; ++mb) {
      for (char& c : block) c = static_cast<char>(g() & 0xff);
      out.write(block.data(), static_cast<std::streamsize>(block.size()));
    }
  }
  ASSERT_EQ(fs::file_size(file), 100u << 20);
  const Result r = run({"run", file, "--out", path("t.csv"), "--stats", path("s.json")});
  expect_refused(*this, r, file, "", "not valid JSON");
  EXPECT_EQ(files(), std::vector<std::string>{"junk.json"});
  fs::remove(file);

  // junk after a valid start: the error is at the field where it begins
  spit(file, R"({"description": "x", "bodies": [)" + std::string(1000, '#'));
  const Result r2 = run({"run", file, "--stats", path("s.json")});
  expect_refused(*this, r2, file, "bodies[0]", "not valid JSON");
  EXPECT_EQ(files(), std::vector<std::string>{"junk.json"});
}

TEST_F(Cli, UnwritableOutputFailsWithoutLeavingAnything) {
  const Result r = run({"run", "pendulum", "--steps", "2", "--out", path("no/such/dir/t.csv")});
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("no/such/dir/t.csv"), std::string::npos) << r.err;
  EXPECT_TRUE(files().empty());
}

}  // namespace

// ---- snapshots: --save-snapshot, --snapshot-every, --resume ----

namespace {

std::string stats_hash(const std::string& file) { return json::parse(slurp(file))["state_hash"].get<std::string>(); }

std::string printed_hash(const std::string& out) {
  const size_t at = out.find("state hash   ");
  return at == std::string::npos ? std::string() : out.substr(at + 13, 16);
}

TEST_F(Cli, SaveAndResumeEqualsOneRunBitForBit) {
  for (const std::string scene : {"pile65", "world1000"}) {
    SCOPED_TRACE(scene);
    const Result whole = run({"run", scene, "--steps", "40", "--stats", path("whole.json")});
    ASSERT_EQ(whole.code, 0) << whole.err;
    const std::string snap = path("half.snap");
    const Result first = run({"run", scene, "--steps", "20", "--save-snapshot", snap});
    ASSERT_EQ(first.code, 0) << first.err;
    EXPECT_NE(first.out.find("snapshot     " + snap), std::string::npos) << first.out;
    const Result second = run({"run", "--resume", snap, "--steps", "20", "--stats", path("resumed.json")});
    ASSERT_EQ(second.code, 0) << second.err;
    EXPECT_EQ(printed_hash(second.out), printed_hash(whole.out));
    EXPECT_EQ(printed_hash(second.out).size(), 16u);
    EXPECT_EQ(stats_hash(path("resumed.json")), stats_hash(path("whole.json")));
    EXPECT_EQ(json::parse(slurp(path("resumed.json")))["resumed_from"], snap);
    // --duration counts from the snapshot too: 20 steps of pile65's dt
    const float dt = json::parse(slurp(path("whole.json")))["dt"].get<float>();
    const Result by_time = run({"run", "--resume", snap, "--duration", std::to_string(20.0 * dt)});
    ASSERT_EQ(by_time.code, 0) << by_time.err;
    EXPECT_EQ(printed_hash(by_time.out), printed_hash(whole.out));
    // no temporary left next to the snapshot
    for (const std::string& f : files()) EXPECT_EQ(f.find(".tmp."), std::string::npos) << f;
    fs::remove(snap);
  }
}

TEST_F(Cli, SnapshotEveryNStepsHoldsTheLastOne) {
  const Result whole = run({"run", "pile65", "--steps", "30"});
  ASSERT_EQ(whole.code, 0) << whole.err;
  // every 7 steps, then the final state at step 25: resuming adds the last 5
  const std::string snap = path("every.snap");
  const Result r = run({"run", "pile65", "--steps", "25", "--save-snapshot", snap, "--snapshot-every", "7"});
  ASSERT_EQ(r.code, 0) << r.err;
  const Result rest = run({"run", "--resume", snap, "--steps", "5"});
  ASSERT_EQ(rest.code, 0) << rest.err;
  EXPECT_EQ(printed_hash(rest.out), printed_hash(whole.out));
  EXPECT_EQ(run({"run", "pile65", "--snapshot-every", "3"}).code, 2) << "needs --save-snapshot";
  EXPECT_EQ(run({"run", "pile65", "--resume", snap}).code, 2) << "a scene and a snapshot";
  EXPECT_EQ(run({"run", "pile65", "--stats", snap, "--save-snapshot", snap}).code, 2) << "the same file twice";
}

TEST_F(Cli, DamagedOrMissingSnapshotIsRefusedByName) {
  const std::string snap = path("w.snap");
  ASSERT_EQ(run({"run", "pile65", "--steps", "5", "--save-snapshot", snap}).code, 0);
  const std::string good = slurp(snap);
  ASSERT_GT(good.size(), 100u);
  struct Damage {
    const char* what;
    std::string bytes;
  };
  std::string flipped = good;
  flipped[good.size() / 2] = static_cast<char>(flipped[good.size() / 2] ^ 0x10);
  std::string magic = good;
  magic[0] = 'X';
  const Damage cases[] = {{"a flipped bit", flipped},
                          {"truncated", good.substr(0, good.size() - 7)},
                          {"header only", good.substr(0, 20)},
                          {"empty", ""},
                          {"bad magic", magic},
                          {"a scene file", R"({"bodies": []})"}};
  for (const Damage& d : cases) {
    SCOPED_TRACE(d.what);
    const std::string bad = path("bad.snap");
    spit(bad, d.bytes);
    const Result r = run({"run", "--resume", bad, "--steps", "3", "--stats", path("s.json"), "--out", path("t.csv")});
    EXPECT_EQ(r.code, 2) << r.out << r.err;
    EXPECT_NE(r.err.find(bad), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(path("s.json")));
    EXPECT_FALSE(fs::exists(path("t.csv")));
  }
  const Result missing = run({"run", "--resume", path("nope.snap")});
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find(path("nope.snap")), std::string::npos) << missing.err;
  // a failed run leaves an existing snapshot as it was
  const Result fails = run({"run", "pile65", "--steps", "2", "--save-snapshot", snap, "--out", path("no/dir/t.csv")});
  EXPECT_EQ(fails.code, 1);
  EXPECT_EQ(slurp(snap), good);
}

}  // namespace
