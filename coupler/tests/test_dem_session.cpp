// The DEM side's session (coupler/dem_session.hpp) against a scripted MPM peer: two MPI ranks
// joined by an intercommunicator as in a coupled run, rank 0 the DEM side (one rank), rank 1
// playing the MPM process message by message. Every test runs on both ranks, in step.
#include <gtest/gtest.h>
#include <mpi.h>

#include <memory>

#include "coupler/dem_session.hpp"

namespace {

MPI_Comm g_inter = MPI_COMM_NULL;    // rank 0 <-> rank 1
// Each test: a fresh duplicate of it on both ranks (collective), owned on the DEM side by its
// link, used by the peer through g_peer
MPI_Comm g_peer = MPI_COMM_NULL;
int g_rank = 0;

bool dem() { return g_rank == 0; }

// the peer's side: raw messages of fixed-layout structs, as mpm_solver's coupled loop sends them
template <class T>
std::vector<T> recv_array(int tag) {
  MPI_Status st;
  MPI_Probe(0, tag, g_peer, &st);
  int bytes = 0;
  MPI_Get_count(&st, MPI_BYTE, &bytes);
  std::vector<T> items(bytes / sizeof(T));
  MPI_Recv(items.data(), bytes, MPI_BYTE, 0, tag, g_peer, MPI_STATUS_IGNORE);
  return items;
}
template <class T>
T recv_struct(int tag) {
  const auto items = recv_array<T>(tag);
  EXPECT_EQ(items.size(), 1u);
  return items.empty() ? T{} : items[0];
}
template <class T>
void send_array(int tag, const std::vector<T> &items) {
  MPI_Send(items.data(), static_cast<int>(items.size() * sizeof(T)), MPI_BYTE, 0, tag, g_peer);
}
template <class T>
void send_struct(int tag, const T &item) {
  send_array(tag, std::vector<T>{item});
}
coupler::StepAck ack(int status, const std::string &message = "", std::int64_t points = 0) {
  coupler::StepAck a;
  a.status = status;
  a.points = points;
  coupler::set_text(a.message, message);
  return a;
}

struct DemSide {
  std::unique_ptr<coupler::Link> link;
  std::unique_ptr<coupler::DemSession> session;
  explicit DemSide(MPI_Comm comm) {
    link = std::make_unique<coupler::Link>(coupler::Intercomm(comm), true, 1.0, "the MPM process");
    session = std::make_unique<coupler::DemSession>(*link, MPI_COMM_SELF, 0);
  }
};

class DemSession : public ::testing::Test {
 protected:
  void SetUp() override {
    MPI_Comm comm;
    MPI_Comm_dup(g_inter, &comm);
    if (dem()) side = std::make_unique<DemSide>(comm);
    else g_peer = comm;
  }
  void TearDown() override {
    side.reset();
    if (g_peer != MPI_COMM_NULL) MPI_Comm_free(&g_peer);
    MPI_Barrier(MPI_COMM_WORLD);
  }
  std::unique_ptr<DemSide> side;
};

coupler::StepHeader header(std::int64_t step, int kind = coupler::kStepCouple) {
  coupler::StepHeader h;
  h.step = step;
  h.kind = kind;
  return h;
}

std::vector<coupler::NodeRecord> two_nodes() {
  std::vector<coupler::NodeRecord> r(2);
  r[0].node = 4, r[1].node = 9;
  return r;
}

TEST_F(DemSession, ExchangeAppliesTheNodeVelocitiesAndSendsTheFrame) {
  if (dem()) {
    DemSide &s = *side;
    std::size_t applied = 0;
    coupler::StepAck a;
    auto h = header(5);
    h.output = 1;
    const auto out = s.session->exchange(
        h, two_nodes(), [&](const std::vector<coupler::NodeUpdate> &u) { applied = u.size(); },
        [] { return std::vector<coupler::GrainRecord>(3); }, a);
    EXPECT_TRUE(out.ok()) << out.what;
    EXPECT_EQ(applied, 2u);
    EXPECT_EQ(a.points, 7);
  } else {
    EXPECT_EQ(recv_struct<coupler::StepHeader>(coupler::kTagStep).step, 5);
    EXPECT_EQ(recv_array<coupler::NodeRecord>(coupler::kTagNodes).size(), 2u);
    send_array(coupler::kTagNodeReply, std::vector<coupler::NodeUpdate>(2));
    send_struct(coupler::kTagStepAck, ack(0, "", 7));
    EXPECT_EQ(recv_array<coupler::GrainRecord>(coupler::kTagGrains).size(), 3u);
  }
}

TEST_F(DemSession, AnErrorOfTheMpmProcessIsReportedWithItsStep) {
  if (dem()) {
    DemSide &s = *side;
    coupler::StepAck a;
    bool applied = false;
    const auto out = s.session->exchange(
        header(30), two_nodes(), [&](const auto &) { applied = true; }, [] { return std::vector<coupler::GrainRecord>(); },
        a);
    EXPECT_EQ(out.status, coupler::StepOutcome::kPeerFailed);
    EXPECT_EQ(out.what, "the MPM process reported an error at step 30: the continuum failed");
    EXPECT_FALSE(applied);
    // every rank's outcome (here one rank): the link stays connected for the finalize hook
    const auto all = s.session->settle(out);
    EXPECT_EQ(all.status, coupler::StepOutcome::kPeerFailed);
    EXPECT_EQ(all.what, out.what);
    EXPECT_EQ(s.link->state(), coupler::Link::State::kConnected);
  } else {
    recv_struct<coupler::StepHeader>(coupler::kTagStep);
    recv_array<coupler::NodeRecord>(coupler::kTagNodes);
    send_struct(coupler::kTagStepAck, ack(1, "the continuum failed"));
  }
}

TEST_F(DemSession, AReplyOfTheWrongSizeIsAProtocolError) {
  if (dem()) {
    DemSide &s = *side;
    coupler::StepAck a;
    const auto out = s.session->exchange(header(1), two_nodes(), [](const auto &) {},
                                         [] { return std::vector<coupler::GrainRecord>(); }, a);
    EXPECT_EQ(out.status, coupler::StepOutcome::kNoPeer);
    EXPECT_EQ(out.what, "protocol error: 1 node velocities for 2 nodes");
  } else {
    recv_struct<coupler::StepHeader>(coupler::kTagStep);
    recv_array<coupler::NodeRecord>(coupler::kTagNodes);
    send_array(coupler::kTagNodeReply, std::vector<coupler::NodeUpdate>(1));
  }
}

TEST_F(DemSession, NoReplyWithinTheTimeoutMarksThePeerHung) {
  if (dem()) {
    DemSide &s = *side;
    coupler::StepAck a;
    const auto out = s.session->exchange(header(8), two_nodes(), [](const auto &) {},
                                         [] { return std::vector<coupler::GrainRecord>(); }, a);
    EXPECT_EQ(out.status, coupler::StepOutcome::kNoPeer);
    EXPECT_NE(out.what.find("no reply from the MPM process within 1 s while waiting for the node velocities of step 8"),
              std::string::npos)
        << out.what;
    s.session->settle(out);
    EXPECT_EQ(s.link->state(), coupler::Link::State::kUnresponsive);
  } else {
    recv_struct<coupler::StepHeader>(coupler::kTagStep);
    recv_array<coupler::NodeRecord>(coupler::kTagNodes);    // and no answer
  }
}

TEST_F(DemSession, RezoneRunsItsThreeRoundTrips) {
  constexpr std::size_t kCells = 6;
  if (dem()) {
    DemSide &s = *side;
    coupler::StepAck a;
    auto h = header(41, coupler::kStepRezone);
    h.zone_source = coupler::kZonesGiven;
    std::vector<signed char> zones;
    std::vector<coupler::RezoneCell<2>> cells;
    auto out = s.session->rezone_zones<2>(h, std::vector<signed char>(kCells, coupler::kContinuum), {},
                                          [] { return std::vector<std::uint64_t>(); },
                                          std::vector<coupler::CellGrains>(2), kCells, zones, cells, a);
    ASSERT_TRUE(out.ok()) << out.what;
    EXPECT_EQ(zones, std::vector<signed char>(kCells, coupler::kHybrid));
    ASSERT_EQ(cells.size(), 1u);
    EXPECT_EQ(cells[0].cell, 3u);
    std::vector<coupler::GrainCorrection<2>> corrections;
    out = s.session->rezone_corrections<2>(std::vector<coupler::GrainSums<2>>(1), corrections, a);
    ASSERT_TRUE(out.ok()) << out.what;
    ASSERT_EQ(corrections.size(), 1u);
    EXPECT_DOUBLE_EQ(corrections[0].mass_factor, 0.5);
    const double force[3] = {1, 2, 3};
    out = s.session->rezone_finish(force, a);
    EXPECT_TRUE(out.ok()) << out.what;
    EXPECT_EQ(a.points, 12);
  } else {
    EXPECT_EQ(recv_struct<coupler::StepHeader>(coupler::kTagStep).kind, coupler::kStepRezone);
    EXPECT_EQ(recv_array<signed char>(coupler::kTagZones).size(), kCells);
    EXPECT_EQ(recv_array<coupler::CellGrains>(coupler::kTagVolumes).size(), 2u);
    send_array(coupler::kTagZones, std::vector<signed char>(kCells, coupler::kHybrid));
    coupler::RezoneCell<2> cell;
    cell.cell = 3;
    send_array(coupler::kTagRezoneCells, std::vector<coupler::RezoneCell<2>>{cell});
    EXPECT_EQ(recv_array<coupler::GrainSums<2>>(coupler::kTagGrainSums).size(), 1u);
    coupler::GrainCorrection<2> c;
    c.mass_factor = 0.5;
    send_array(coupler::kTagCorrections, std::vector<coupler::GrainCorrection<2>>{c});
    EXPECT_EQ(recv_array<double>(coupler::kTagSupport), (std::vector<double>{1, 2, 3}));
    send_struct(coupler::kTagStepAck, ack(0, "", 12));
  }
}

TEST_F(DemSession, ARezoneThatMovesNoMaterialEndsWithItsAcknowledgement) {
  // no cell to rezone: the acknowledgement follows the zone map at once (the host then changes
  // no atom), and the next rezone's error acknowledgement there is the MPM process's failure
  constexpr std::size_t kCells = 4;
  if (dem()) {
    DemSide &s = *side;
    coupler::StepAck a;
    auto h = header(51, coupler::kStepRezone);
    h.zone_source = coupler::kZonesOracle;
    std::vector<signed char> zones;
    std::vector<coupler::RezoneCell<2>> cells(3);
    auto out = s.session->rezone_zones<2>(h, {}, coupler::OracleSettings{}, [] { return std::vector<std::uint64_t>(); },
                                          {}, kCells, zones, cells, a);
    ASSERT_TRUE(out.ok()) << out.what;
    EXPECT_TRUE(cells.empty());
    EXPECT_EQ(zones, std::vector<signed char>(kCells, coupler::kHybrid));
    EXPECT_EQ(a.points, 9);
    out = s.session->rezone_zones<2>(header(61, coupler::kStepRezone), {}, coupler::OracleSettings{},
                                     [] { return std::vector<std::uint64_t>(); }, {}, kCells, zones, cells, a);
    EXPECT_EQ(out.status, coupler::StepOutcome::kPeerFailed);
    EXPECT_NE(out.what.find("the MPM process could not rezone: points lost"), std::string::npos) << out.what;
  } else {
    for (const char *error : {"", "points lost"}) {
      recv_struct<coupler::StepHeader>(coupler::kTagStep);
      recv_struct<coupler::OracleSettings>(coupler::kTagOracle);
      recv_array<std::uint64_t>(coupler::kTagDiscreteCells);
      recv_array<coupler::CellGrains>(coupler::kTagVolumes);
      send_array(coupler::kTagZones, std::vector<signed char>(kCells, coupler::kHybrid));
      send_array(coupler::kTagRezoneCells, std::vector<coupler::RezoneCell<2>>());
      send_struct(coupler::kTagStepAck, ack(*error ? 1 : 0, error, 9));
    }
  }
}

TEST_F(DemSession, RezoneZonesOfTheWrongSizeAreAProtocolErrorAndTheOracleGetsItsSettings) {
  if (dem()) {
    DemSide &s = *side;
    coupler::StepAck a;
    auto h = header(61, coupler::kStepRezone);
    h.zone_source = coupler::kZonesOracle;
    coupler::OracleSettings oracle;
    oracle.band = 0.25;
    oracle.surface_depth = 0.5;    // the last field of the layout
    std::vector<signed char> zones;
    std::vector<coupler::RezoneCell<3>> cells;
    const auto out = s.session->rezone_zones<3>(h, {}, oracle, [] { return std::vector<std::uint64_t>{7, 8}; }, {}, 10,
                                                zones, cells, a);
    EXPECT_EQ(out.status, coupler::StepOutcome::kNoPeer);
    EXPECT_EQ(out.what, "protocol error: a zone map of 4 cells for a grid of 10");
  } else {
    recv_struct<coupler::StepHeader>(coupler::kTagStep);
    const auto oracle = recv_struct<coupler::OracleSettings>(coupler::kTagOracle);
    EXPECT_DOUBLE_EQ(oracle.band, 0.25);
    EXPECT_DOUBLE_EQ(oracle.surface_depth, 0.5);
    EXPECT_EQ(recv_array<std::uint64_t>(coupler::kTagDiscreteCells), (std::vector<std::uint64_t>{7, 8}));
    EXPECT_TRUE(recv_array<coupler::CellGrains>(coupler::kTagVolumes).empty());
    send_array(coupler::kTagZones, std::vector<signed char>(4, coupler::kDiscrete));
  }
}

TEST_F(DemSession, ALoadedStateBringsItsZonesAndAFailedSaveItsMessage) {
  if (dem()) {
    DemSide &s = *side;
    coupler::StepAck a;
    std::vector<signed char> zones(5, coupler::kDiscrete);
    auto out = s.session->state_request(header(100, coupler::kStepLoad), "state.mpm.h5", 12, zones, a);
    ASSERT_TRUE(out.ok()) << out.what;
    EXPECT_EQ(zones, std::vector<signed char>(5, coupler::kContinuum));
    EXPECT_EQ(a.points, 40);
    out = s.session->state_request(header(200, coupler::kStepSave), "x.mpm.h5", 12, zones, a);
    EXPECT_EQ(out.status, coupler::StepOutcome::kPeerFailed);
    EXPECT_EQ(out.what, "saving the MPM state failed: disk full");
    const std::string too_long(sizeof(coupler::StateRequest::path), 'x');
    out = s.session->state_request(header(300, coupler::kStepSave), too_long, 12, zones, a);
    EXPECT_EQ(out.status, coupler::StepOutcome::kNoPeer);
    EXPECT_NE(out.what.find("is too long"), std::string::npos) << out.what;
  } else {
    EXPECT_EQ(recv_struct<coupler::StepHeader>(coupler::kTagStep).kind, coupler::kStepLoad);
    const auto request = recv_struct<coupler::StateRequest>(coupler::kTagState);
    EXPECT_EQ(coupler::get_text(request.path), "state.mpm.h5");
    EXPECT_EQ(request.exchanges, 12);
    send_array(coupler::kTagZones, std::vector<signed char>(5, coupler::kContinuum));
    send_struct(coupler::kTagStepAck, ack(0, "", 40));
    recv_struct<coupler::StepHeader>(coupler::kTagStep);
    recv_struct<coupler::StateRequest>(coupler::kTagState);
    send_struct(coupler::kTagStepAck, ack(1, "disk full"));
  }
}

TEST(DemSessionOutcome, EveryRankTakesTheLowestFailingRanksOutcome) {
  // over MPI_COMM_WORLD's two ranks: rank 1 fails, rank 0 does not
  coupler::StepOutcome mine;
  if (!dem()) mine.fail(coupler::StepOutcome::kPeerFailed, "rank 1's reason");
  auto all = coupler::agree_on_outcome(MPI_COMM_WORLD, mine);
  EXPECT_EQ(all.status, coupler::StepOutcome::kPeerFailed);
  EXPECT_EQ(all.what, "rank 1's reason");
  // both fail: rank 0's message and status
  mine.fail(dem() ? coupler::StepOutcome::kNoPeer : coupler::StepOutcome::kPeerFailed, dem() ? "first" : "second");
  all = coupler::agree_on_outcome(MPI_COMM_WORLD, mine);
  EXPECT_EQ(all.status, coupler::StepOutcome::kNoPeer);
  EXPECT_EQ(all.what, "first");
  EXPECT_TRUE(coupler::agree_on_outcome(MPI_COMM_WORLD, {}).ok());
}

}    // namespace

int main(int argc, char **argv) {
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_MULTIPLE, &provided);
  int size = 0;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
  if (size != 2) {
    if (g_rank == 0) std::fprintf(stderr, "test_dem_session: run with 2 MPI ranks (tools/mpirun.sh -np 2)\n");
    MPI_Finalize();
    return 2;
  }
  ::testing::InitGoogleTest(&argc, argv);
  MPI_Comm local;
  MPI_Comm_split(MPI_COMM_WORLD, g_rank, 0, &local);
  MPI_Intercomm_create(local, 0, MPI_COMM_WORLD, 1 - g_rank, 77, &g_inter);
  const int failed = RUN_ALL_TESTS();
  int any = 0;
  MPI_Allreduce(&failed, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Comm_free(&g_inter);
  MPI_Comm_free(&local);
  MPI_Finalize();
  return any;
}
