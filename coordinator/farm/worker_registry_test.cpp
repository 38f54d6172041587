// The farm's cores as the registry counts them for cutting rounds, and the share of the
// registry one address may hold: bounds a holder of the worker token cannot pass with
// names, which cost it nothing (docs/SECURITY.md, "Cores and names one address counts").
#include "worker_registry.h"

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <set>
#include <string>

#include "coordinator.h"
#include "farm_test_results.h"
#include "lease_table.h"
#include "unix_millis.h"

namespace aliquot {
namespace {

class WorkerRegistryTest : public ::testing::Test {
protected:
    WorkerRegistryTest() { limits.lost_after = std::chrono::hours(1); }

    WorkerRegistry& registry() {
        if (!registry_)
            registry_ = std::make_unique<WorkerRegistry>(limits, archive_, events_,
                                                         [this] { return holding; });
        return *registry_;
    }
    // Registers `name` from `address` ("ipv4:..."), its link holding a lease a thread
    // (a worker at work) when `busy`.
    std::string add(const std::string& name, uint32_t threads, const std::string& address,
                    bool busy) {
        std::string link = registry().register_link(name, threads, address, false);
        if (busy) holding[link] = threads;
        return link;
    }
    void merge(const std::string& name, int jobs) {
        for (int i = 0; i < jobs; ++i) registry().note_merged(name, 1000, 0.1);
    }

    WorkerLimits limits;
    WorkerRegistry::LeasesByLink holding;  // the links holding leases, and how many

private:
    RenderArchive archive_{""};
    RenderEvents events_;
    std::unique_ptr<WorkerRegistry> registry_;
};

// A worker registered and heard from, but taking no job, adds no core: one holder of the
// worker token kept 4096 such names alive, each stating 1024 threads, and every round of
// every render was cut into the smallest tiles. A worker counts from its first lease (at
// the next count, every tick) or merge (at once) until two working windows after its
// last merge; the embedded render's threads, in this process, count always.
TEST_F(WorkerRegistryTest, ThreadsCountOnlyForWorkersThatShowTheyWork) {
    add("idle", 1024, "ipv4:10.0.0.1", false);
    EXPECT_EQ(registry().alive_cores(), 0u);
    add("leasing", 8, "ipv4:10.0.0.2", true);
    registry().tick(unix_millis_now(), false);
    EXPECT_EQ(registry().alive_cores(), 8u);
    add("merging", 16, "ipv4:10.0.0.3", false);
    EXPECT_EQ(registry().alive_cores(), 8u);
    merge("merging", 16);
    EXPECT_EQ(registry().alive_cores(), 24u);
    registry().register_link("in-process", 4, "process:in-process", true);
    EXPECT_EQ(registry().alive_cores(), 28u);
    // Two working windows after its last merge, a worker holding no lease stops counting.
    registry().tick(unix_millis_now() + 2 * limits.working_within.count() + 1000, false);
    EXPECT_EQ(registry().alive_cores(), 12u);
}

// An honest worker idle between rounds longer than a lease (a denoised round's end of
// 17-25 s at 1080p with --lease-seconds 5, a straggler, a gap between renders) still
// counts: the working window is at least 10 minutes whatever the lease time. With a
// window of one lease time it counted no core after 5 s, and the next round was cut for
// almost no one.
TEST_F(WorkerRegistryTest, AWorkerIdleBetweenRoundsCountsWhateverTheLeaseTime) {
    EXPECT_EQ(working_window(std::chrono::seconds(5)), std::chrono::minutes(10));
    EXPECT_EQ(working_window(std::chrono::hours(1)), std::chrono::hours(1));
    limits.working_within = working_window(std::chrono::seconds(5));
    add("honest", 16, "ipv4:10.0.0.3", false);
    merge("honest", 32);
    registry().tick(unix_millis_now() + 25000, false);
    EXPECT_EQ(registry().alive_cores(), 16u);
}

// A name counts no more of the threads it states than it has shown work for: the granted
// leases its links hold now plus the jobs it merged in the working window. One lease
// renewed forever, or one cheap merge a window, counted all 1024 threads of a name.
TEST_F(WorkerRegistryTest, ANameCountsAsManyThreadsAsItHoldsLeasesAndMergedJobs) {
    const std::string renewing = add("renewing", 1024, "ipv4:10.0.0.1", false);
    holding[renewing] = 1;
    add("merged-once", 1024, "ipv4:10.0.0.2", false);
    merge("merged-once", 1);
    registry().tick(unix_millis_now(), false);
    EXPECT_EQ(registry().alive_cores(), 2u);
    holding[renewing] = 3;
    merge("renewing", 2);
    merge("merged-once", 9);
    registry().tick(unix_millis_now(), false);
    EXPECT_EQ(registry().alive_cores(), 15u);
}

// A lease only reserved (being issued: it may come to no job) shows no work yet; one
// granted does.
TEST_F(WorkerRegistryTest, AReservedLeaseCountsNoCore) {
    LeaseTable leases;
    const std::string link = add("asking", 8, "ipv4:10.0.0.1", false);
    const uint64_t id = leases.reserve(link);
    holding = leases.leases_by_link();
    EXPECT_EQ(holding.count(link), 1u);  // held: its link is not dropped meanwhile
    registry().tick(unix_millis_now(), false);
    EXPECT_EQ(registry().alive_cores(), 0u);
    leases.grant(id, "render", "render/0");
    holding = leases.leases_by_link();
    registry().tick(unix_millis_now(), false);
    EXPECT_EQ(registry().alive_cores(), 1u);
}

// A Register of a known name with its threads, address and trust as they were changes no
// count, so it recounts nothing (a recount allocates; a Register flood forced one on
// every Lease and Complete): a lease taken since is counted at the next tick, as without
// it. A Register that changes the threads recounts at once.
TEST_F(WorkerRegistryTest, ARegisterAsBeforeRecountsNothing) {
    const std::string link = add("w", 8, "ipv4:10.0.0.1", false);
    EXPECT_EQ(registry().alive_cores(), 0u);
    holding[link] = 8;
    add("w", 8, "ipv4:10.0.0.1", false);
    EXPECT_EQ(registry().alive_cores(), 0u);
    add("w", 4, "ipv4:10.0.0.1", false);
    EXPECT_EQ(registry().alive_cores(), 4u);
    // Nor are the identities jobs may go to rebuilt for it.
    const auto identities = registry().alive_identities();
    add("w", 4, "ipv4:10.0.0.1", false);
    EXPECT_EQ(registry().alive_identities(), identities);
    add("w", 4, "ipv4:10.0.0.2", false);
    EXPECT_EQ(registry().alive_identities()->count("ipv4:10.0.0.2"), 1u);
}

// Several workers on one machine share its cores, so one address counts at most
// kMaxWorkerThreads, however many names work from it; workers on addresses of their own
// (docker compose, a farm on a LAN) count as before, each its threads.
TEST_F(WorkerRegistryTest, OneAddressCountsAtMostOneMachinesThreads) {
    limits.max_workers_per_host = limits.max_workers = limits.max_links = 8192;
    for (int i = 0; i < 3; ++i)
        add("proc-" + std::to_string(i), 16, "ipv4:10.0.0.1", true);
    for (int i = 0; i < 8; ++i)
        add("compose-" + std::to_string(i), 16, "ipv4:172.18.0." + std::to_string(i + 2),
            true);
    registry().tick(unix_millis_now(), false);
    EXPECT_EQ(registry().alive_cores(), 3u * 16 + 8u * 16);  // every thread, as before
    for (int i = 0; i < 4096; ++i)
        add("flood-" + std::to_string(i), 1024, "ipv4:10.0.0.9", true);
    registry().tick(unix_millis_now(), false);
    EXPECT_EQ(registry().alive_cores(), 3u * 16 + 8u * 16 + kMaxWorkerThreads);
}

// One address holds at most max_workers_per_host names and links: past it a Register is
// refused, saying so, while other addresses still register and a worker of that address
// registers again under its own name.
TEST_F(WorkerRegistryTest, AnAddressHoldsAtMostItsShareOfTheRegistry) {
    limits.max_workers_per_host = 4;
    for (int i = 0; i < 4; ++i) add("w" + std::to_string(i), 1, "ipv4:10.0.0.9", false);
    try {
        add("w4", 1, "ipv4:10.0.0.9", false);
        ADD_FAILURE() << "a fifth name from one address was registered";
    } catch (const TooManyWorkers& e) {
        EXPECT_NE(std::string(e.what()).find("ipv4:10.0.0.9 has 4 workers registered"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_FALSE(registry().knows("w4"));
    EXPECT_NO_THROW(add("other", 1, "ipv4:10.0.0.8", false));
    EXPECT_NO_THROW(add("w0", 1, "ipv4:10.0.0.9", false));  // again: its old link goes
    EXPECT_EQ(registry().links(), 5u);
}

// A worker of that address that is lost (a process that restarted under a new name)
// makes room for a new name; one holding a lease never does.
TEST_F(WorkerRegistryTest, AnAddressAtItsShareMakesRoomOnlyWithItsOwnLostWorkers) {
    limits.max_workers_per_host = 2;
    limits.lost_after = std::chrono::milliseconds(-1);  // every worker is lost at once
    add("old", 1, "ipv4:10.0.0.9", false);
    add("busy", 1, "ipv4:10.0.0.9", true);
    add("other", 1, "ipv4:10.0.0.8", false);
    EXPECT_NO_THROW(add("new", 1, "ipv4:10.0.0.9", true));
    EXPECT_FALSE(registry().knows("old"));
    EXPECT_TRUE(registry().knows("busy"));
    EXPECT_TRUE(registry().knows("other"));
    EXPECT_THROW(add("newer", 1, "ipv4:10.0.0.9", false), TooManyWorkers);
}

// The same through the Coordinator: the jobs the first round of a 256x256 render is cut
// into (uniform, 8 spp: one round; 28 jobs for a farm of a few cores, 256 tiles of 16 for
// 1024 cores and more), leased by one honest worker until none is left.
class WorkerCoresTest : public ::testing::Test {
protected:
    WorkerCoresTest() {
        options.worker_lost_after = std::chrono::hours(1);
        spec.width = spec.height = 256;
        spec.strategy.spp = 8;
    }
    size_t jobs_of_next_render(Coordinator& c, const std::string& honest) {
        c.submit(spec);
        size_t jobs = 0;
        while (c.lease(honest, std::chrono::milliseconds(0))) ++jobs;
        return jobs;
    }

    CoordinatorOptions options;
    RenderSpec spec = small_test_spec();
};

TEST_F(WorkerCoresTest, IdleNamesFromOneAddressLeaveTheCutOfOneHonestWorker) {
    options.max_workers_per_host = 4096;  // the count alone, not the share, is tested
    size_t honest_alone = 0;
    {
        Coordinator c(options);
        honest_alone = jobs_of_next_render(
            c, c.register_worker("honest", 4, "ipv4:10.0.0.1:5").session);
    }
    Coordinator c(options);
    for (int i = 0; i < 4095; ++i)
        c.register_worker("idle-" + std::to_string(i), kMaxWorkerThreads,
                          "ipv4:10.0.0.9:" + std::to_string(1000 + i));
    const std::string honest = c.register_worker("honest", 4, "ipv4:10.0.0.1:5").session;
    EXPECT_EQ(jobs_of_next_render(c, honest), honest_alone);
    EXPECT_EQ(honest_alone, 28u);
}

// A worker stating 1024 threads that never takes a job leaves the cut as it was; one
// merge counts one of its threads, not 1024; once it has merged 84 jobs, the next render
// is cut for them (88 cores with the honest worker's 4: 256 jobs).
TEST_F(WorkerCoresTest, AWorkerCountsOnceItTakesJobs) {
    Coordinator c(options);
    const std::string big = c.register_worker("big", 1024, "ipv4:10.0.0.2:5").session;
    const std::string honest = c.register_worker("honest", 4, "ipv4:10.0.0.1:5").session;
    EXPECT_EQ(jobs_of_next_render(c, honest), 28u);
    const auto merge_all = [&] {
        while (const auto grant = c.lease(big, std::chrono::milliseconds(0)))
            ASSERT_EQ(c.complete(big, grant->lease_id, zero_result(*grant)).status,
                      CompleteStatus::Merged);
    };
    c.submit(spec);
    const auto grant = c.lease(big, std::chrono::milliseconds(0));
    ASSERT_TRUE(grant);
    ASSERT_EQ(c.complete(big, grant->lease_id, zero_result(*grant)).status,
              CompleteStatus::Merged);
    while (c.lease(honest, std::chrono::milliseconds(0))) {
    }
    EXPECT_EQ(jobs_of_next_render(c, honest), 28u);
    for (int i = 0; i < 3; ++i) c.submit(spec);
    merge_all();
    EXPECT_EQ(jobs_of_next_render(c, honest), 256u);
}

}  // namespace
}  // namespace aliquot
