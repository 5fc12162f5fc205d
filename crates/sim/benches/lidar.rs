//! Ray-casting cost of one full VLP-16 revolution (28,800 rays) over full-size (200 m x 16 rows) fields.
//! ns/ray = time per revolution / 28,800.
//!
//! `cargo bench -p croprow-sim --bench lidar -- --warm-up-time 1 --measurement-time 3`
//!
//! Measured 2026-11-22 on the shared 2-core AMD EPYC build machine (load average 3-5, so wall times
//! are noisy: compare instruction counts). Before -> after the per-cell height ranges (commit 76b93fa),
//! median wall time per revolution, both binaries run back to back:
//! young corn 4.00 -> 3.66 ms, grown corn 8.26 -> 5.01 ms, young soybean 4.34 -> 3.85 ms,
//! grown soybean 8.28 -> 5.77 ms, curved corn 4.00 -> 4.67 ms (CPU time of the same scans measured
//! alone: 4.2 -> 3.9 ms, i.e. unchanged within the noise). Instructions per revolution (callgrind on
//! `examples/raycast_cost.rs`, `Lidar::cast_columns` only): young corn 32.4M -> 22.5M, grown corn 55.7M -> 30.4M, young soybean
//! 39.0M -> 24.8M, grown soybean 68.2M -> 31.7M, curved corn 33.3M -> 23.6M. The scans are bit for bit
//! the same as before. The 1 ms target is not met: a downward ray (13k of the 28.8k) still costs
//! ~2,200 instructions (grown corn: 16 cells, 30 primitive references, 10 primitive tests); getting
//! under 1 ms needs SIMD primitive tests over structure-of-arrays cells, not more culling.
//!
//! Coarse height blocks (4 × 4 cells, commit 8265261), instructions per revolution as above, before ->
//! after, scans bit for bit the same: young corn 22.35M -> 22.15M, grown corn 29.01M -> 27.75M, young
//! soybean 24.80M -> 24.56M, grown soybean 31.63M -> 30.58M, curved corn 23.34M -> 22.58M. A ray reaching
//! the canopy steps 16 cells (12 of them over the canopy), 3.6 cells hold something under it, and it
//! tests 10 primitives (grown corn); a 0.4 m block almost always holds a row crest, so few steps go.
//!
//! Rasterising the primitives into the range image instead (commit f94e492, reverted in 8e0f099:
//! bounding-sphere footprints in beam x column space, exact intersections per pixel, front-to-back
//! buckets, the marcher for rays whose answer lies beyond 5 m) is exact but slower: grown corn 51M,
//! young corn 26M instructions per revolution. Within 5 m of the sensor a grown-corn revolution gathers
//! 23k primitives (113k cell references) for 10k resolved rays, and loose spheres around long leaves
//! leave ~14 intersection tests per pixel; the 19k rays left to the marcher cost 8M on their own.
//!
//! Beam packets (`scene/packet.rs`, branch `raycast`): each laser's rays at 8 consecutive azimuths walk
//! the grid together and each primitive is tested on all 8 at once (SSE-vectorised lanes). Measured
//! 2026-11-22, load average 7-10 on the 2 cores, so criterion's wall times were about twice the CPU
//! time and are not quoted: CPU time per revolution (`examples/raycast_cost.rs`, 30 revolutions,
//! median of 3 runs alternating the binaries before -> after): young corn 4.27 -> 2.72 ms, grown corn
//! 5.67 -> 3.85 ms, young soybean 4.30 -> 3.34 ms, grown soybean 5.74 -> 4.91 ms, curved corn
//! 4.64 -> 3.21 ms. Instructions per revolution hardly moved (callgrind, as above, with the 6 m reach
//! of commit "packet: reach 6 m": 22.2M -> 20.4M, 27.7M -> 26.3M, 24.6M -> 23.2M, 30.6M -> 30.5M,
//! 22.6M -> 20.8M): the gain is fewer memory stalls
//! (a packet loads each cell's list and each primitive once for 8 rays) and packed arithmetic. Scans
//! are bit for bit the same except where a ray grazes a stalk's rim: the cylinder test now returns the
//! nearer of its wall and top hits (it returned the wall hit even when f32 rounding put the top a
//! hair nearer), 2 of 423k points of 30 young-corn revolutions moved, by 0.4 mm, 5 in young soybean,
//! by up to 1.1 mm; same classes and counts. Still 3-4x short of the 1 ms target: the 8-lane patch test
//! (~165 instructions) runs ~23 times per packet: a third of the instructions.
//!
//! Table of tested primitives (branch `simperf3`): a packet tests each primitive once (a 64-entry
//! direct-mapped table; a leaf lies in several cells of a walk, and half the 8-lane patch tests were
//! repeats that cannot find a nearer hit), packets whose rays all rise return before any lane is set
//! up, and the spread of the lanes is branch-free. Instructions per revolution (callgrind as above, 3
//! revolutions) before -> after: young corn 20.4M -> 17.1M, grown corn 26.3M -> 20.7M, young soybean
//! 23.2M -> 19.2M, grown soybean 30.5M -> 23.9M, curved corn 20.8M -> 17.6M; data-cache misses
//! unchanged (callgrind `--cache-sim=yes --LL=2097152,16,64`, 3 grown-corn revolutions: D1 262k, LL
//! 116k either way). Scans bit for bit the same (scan hashes of all five scenarios). CPU times were not
//! measurable to better than ±20 % that day (load average 10-11 on the 2 cores): grown corn 3.8-4.6
//! ms before, 4.0-5.0 ms after, young corn 3.0-3.4 / 2.8-3.0 ms.
//!
//! Tried on that branch and dropped (scans bit for bit the same in every case):
//! - planes round each packet's fan (the laser's cone plane and the side planes of its outermost
//!   rays) that reject a primitive whose hull (40 bytes a primitive) no lane can reach: 8-lane tests
//!   47k -> 14.5k per grown-corn revolution (5k of them hit), but the test cost as many instructions
//!   as it saved and the hull array added 10 % L2 misses;
//! - rasterising each frame (180 columns x 16 lasers) in the sensor's (column, laser) grid: cells in
//!   square rings round the sensor within the frame's sector, each primitive's hull projected to a
//!   rectangle of rays (polynomial arctangent, bounds widened past its error), exact tests on those
//!   rays only, occlusion tiles of 8 columns: 44M instructions per grown-corn revolution, twice the
//!   packets. 23k primitives within 6 m are projected per revolution (~400 instructions each) and a
//!   closed canopy cannot be culled cell by cell (each cell's column spans the whole canopy depth, so
//!   some ray over it is always still searching);
//! - 16 lanes: -3 % instructions; reach 4 m / 8 m: +7 % / +1.5 %; cells of 0.07 m / 0.15 m: +5 % /
//!   +1 %.
//!
//! AVX2 build (branch `simperf4`): the packet code (`scene/packet.rs`, one source with every callee
//! `#[inline(always)]`) is compiled a second time under `#[target_feature(enable = "avx2")]` and picked
//! when the scene is built (`is_x86_feature_detected!`); no FMA, so both builds return the same bits (a
//! test compares them ray by ray, and the packet-vs-single-ray tests run on both). The AVX2 build never
//! halves the lanes (one register holds 8), and both settle the lanes' stopping distance once per strip
//! instead of at every hit. Measured 2026-11-22 on the shared 2-core AMD EPYC (AVX2 and AVX-512; load
//! average 6-8 from other builds, so CPU times are noisy). Instructions per revolution (callgrind as
//! above, 3 revolutions) before -> after: young corn 17.06M -> 16.15M, grown corn 20.67M -> 18.82M,
//! young soybean 19.17M -> 17.89M, grown soybean 23.91M -> 21.35M, curved corn 17.57M -> 16.68M; scan
//! hashes of all five scenarios unchanged. CPU time per revolution (`examples/raycast_cost.rs`, 50
//! revolutions, 10 runs alternating the binaries, median / min): young corn 2.68 / 2.10 -> 2.42 / 2.10
//! ms, grown corn 3.61 / 2.82 -> 3.18 / 2.45 ms, young soybean 3.22 / 2.59 -> 2.94 / 2.22 ms, grown
//! soybean 4.55 / 3.98 -> 4.20 / 3.02 ms. The world alone (`examples/world_cost.rs`, 8 s, CPU time, 5
//! runs, median real-time factor): grown corn 27.8 -> 30.4, young corn 38.2 -> 43.0. The 8-lane patch
//! test was already a small share once packed 4-wide: in the AVX2 build it costs ~48 instructions (52k
//! tests a grown-corn revolution, 2.5M), the walk's bookkeeping (strips, cell lists, footprints, the
//! table, lane spreads) ~11M, the rays past the reach 2M and the LiDAR's own work (rotations, noise,
//! points) 2.5M. The baseline build of the same source costs 8 % more instructions than before
//! (grown corn 22.4M: the forced inlining changes its register use) at the same CPU time within the
//! noise (grown corn median 3.74 vs 3.69 ms). Tried and dropped: testing the table before the footprint
//! (+0.7 % instructions); leaving `settle`, `retire` and `visit` to the inliner (+20 % in the AVX2
//! build, where they were then compiled for the baseline, +5 % in the baseline build).
//!
//! Outside the caster there is nothing left to take (callgrind on `croprow bench`, grown corn): per
//! 0.1 s simulated, the LiDAR's casting costs ~19M instructions, the rest of `World::step` (robot,
//! wheel odometry, IMU, crop contacts) ~27k, the EKF fusion ~47k and the `Navigator` (detector, lane
//! switching, MPC) ~2.4M; `croprow bench --json` gave `sim_realtime_factor` 12.1 -> 14.4 (median of 8
//! runs alternating the binaries, wall time at load average 7 on 2 cores).
//!
//! The 1 ms target needs 5x fewer instructions (~4M a revolution, ~300 per ray that hits); the
//! cost is spread over the walk (strips, cells, ~70 cell references a packet), 8-lane tests and the
//! rays left to `Scene::cast_from` past the reach (1.9k a revolution, ~800 instructions each).
//!
//! The whole closed loop, then the walk's bookkeeping (branch `simperf5`). Where a 0.1 s step of
//! `croprow bench`'s loop goes (callgrind on `examples/loop_cost.rs 4`, grown corn, 40 scans;
//! instructions per step, before -> after): in all 22.7M -> 19.7M; the LiDAR's casting 18.93M ->
//! 16.18M (82 %); the detector 3.41M -> 3.19M (preprocessing 2.10M -> 1.88M, of which levelling
//! 0.86M -> 0.73M; lanes 1.31M); lane switching and MPC 0.22M; the EKF 0.05M; the rest of
//! `World::step` 0.04M. On young soybean, where levelling fits every scan and refits every return,
//! preprocessing went from 2.84M to 2.46M a scan (levelling ~1.90M -> 1.52M: the returns are made
//! sensor-relative in f64 once for the four refit passes, and only when a fit gets that far; cells
//! are indexed through `i64`, not `usize`). The criterion bench `detector` could not resolve it at
//! load average 11 (default `Preprocess` -9 %, p = 0.01, but unchanged stages moved ±20 %). Changes,
//! every one leaving the scans bit for bit (scan hashes of all five
//! scenarios) and 20 m closed-loop runs byte for byte (`croprow simulate`, grown corn and young
//! soybean: trajectory, detections, metrics):
//! - stalks and weed clumps are tested out of line (`Lanes::each`): inlined, their unrolled 8 lanes
//!   had the compiler hoist the 24 direction components out of the cell loop and copy them on the
//!   stack at every strip (~80 instructions a strip, 14k strips a grown-corn revolution): -9 %;
//! - primitive footprints stored per axis, a packet reading the one across its walk: -2.7 %;
//! - the lanes' minima and maxima by halving (packed), the stopping rule as a select, the strip's
//!   ends from its boundary rays, its cells by stride: -1.4 %;
//! - the LiDAR: packets write their hits in place per beam, the rays are rotated as packed arrays per
//!   axis in plain loops (an array `map`'s closure was not inlined): -2 %.
//!
//! Instructions per revolution (callgrind as above, 3 revolutions) before -> after: young corn
//! 16.15M -> 13.91M, grown corn 18.82M -> 16.09M, young soybean 17.89M -> 15.51M, grown soybean
//! 21.35M -> 18.41M, curved corn 16.68M -> 14.44M (-13 to -15 %). CPU time, measured at load average
//! 11-12 on the 2 cores (other builds), so only indicative: per revolution (`examples/raycast_cost.rs`,
//! 30 revolutions, 5 runs alternating the binaries, median) grown corn 3.19 -> 2.82 ms, young corn
//! 2.33 -> 2.10 ms, young soybean 2.69 -> 2.58 ms; the world alone (`examples/world_cost.rs`, 8 s, 5
//! runs, median real-time factor) grown corn 34.5 -> 38.8, young corn 46.3 -> 51.1; `croprow bench
//! --json` `sim_realtime_factor` (wall time, 5 runs alternating, median) 15.1 -> 16.0.
//!
//! CPU time falls less than instructions because a third of the packet code's time (perf, cpu-clock
//! samples, grown corn) waits on three loads: a cell's first primitive reference, the primitive's
//! footprint and the primitive itself. What a grown-corn revolution still costs: 26k 8-lane patch
//! tests at ~120 instructions with the register spills round them (3.1M), ~130k cell references
//! scanned (2.1M), 14k strips (1.1M), 2k rays past the reach (1.6M), the LiDAR's own work (rotations,
//! noise draws, points: 2.7M).
//! Tried and dropped: primitives aligned to a 64-byte cache line (56 bytes straddle two lines five
//! times in eight; no CPU time gain within the noise, 14 % more memory); settling rising rays before
//! the square root in `packet_ray` (+0.2 %); RANSAC scoring that stops once a hypothesis cannot win
//! (levelling +1 %: grown corn's hypotheses are all poor, so it never stops early).
//!
//! Data layout (branch `simperf6`): nothing kept. Per revolution (callgrind on
//! `examples/raycast_cost.rs`, 3 revolutions, `--cache-sim=yes --LL=2097152,16,64`, casting only) the
//! caster costs young corn 13.9M instructions, 37.0k D1 and 12.2k LL read misses; grown corn 16.1M,
//! 76.7k, 34.3k; young soybean 15.5M, 59.6k, 28.7k; grown soybean 18.4M, 122.3k, 58.8k. In grown corn
//! the misses fall on a cell's first reference (24 %), the primitive (18 %), its footprint (14 %),
//! the cell's record (5 %), its height (4 %) and the LiDAR's ray table (7 %). Each change below left
//! the scans bit for bit the same (scan hashes of all five scenarios; the first also 20 m
//! `croprow simulate` runs of grown corn and young soybean byte for byte) and none moved the CPU time
//! (medians of 8 runs alternating the binaries, load average 9-13 on the 2 cores, so only differences
//! over ~5 % would show):
//! - primitives stored in grid order (by the 4 × 4-cell block, then the cell, of their centre) and the
//!   cells' lists laid out block by block: grown corn D1 misses -7 %, LL +2 %; young corn D1 +4 %, LL
//!   +20 %; young soybean D1 +2 %, LL +10 %; grown soybean D1 -3 %, LL +1.5 %. Blocks alone, lists
//!   alone and order alone were no better. CPU per simulated 0.1 s of the closed loop
//!   (`loop_cost.rs`, grown / young corn) 3.27 / 2.65 ms before, 3.31 / 2.62 after; `croprow bench
//!   --json` `sim_realtime_factor` (wall time) 18.6 before, 16.9 after;
//! - then 8-byte cell references (heights in quarter millimetres, rounded outwards, so a superset of
//!   the primitives is tested): grown corn D1 misses -11 %, LL -18 %, but +8 % instructions (up to 4 %
//!   more tests, and the reference loop spills registers); CPU time unchanged;
//! - prefetching the first reference of the next strip's cells (`_mm_prefetch`): unchanged;
//! - the reference loop's three tests (height, footprint, table) as one branch: unchanged.
//!
//! What the profile says instead: callgrind's branch model (`--branch-sim=yes`) counts 136k
//! mispredicted conditional branches in a grown-corn revolution (of 2.0M; young corn 120k of 1.7M,
//! young soybean 126k of 2.0M): a reference's height tests
//! (11 and 15 % of their runs), its footprint test (12 %), the table (41 %), the cell's height (17 %).
//! At ~15
//! cycles each that is ~2M cycles, as much as the cache misses; the samples `perf` puts on the
//! loads after those branches are largely these. Sifting each cell's list without a branch per
//! reference (the passing indices written to a small array, then tested in order) cut them by 27 %
//! but cost 19 % more instructions (28 instead of 12 a reference): CPU time unchanged. The caster
//! runs at about 2 instructions a cycle: the 1 ms target needs about 4M instructions a revolution,
//! i.e. a different algorithm (fewer references scanned per ray), not a layout or a branch shape.
//!
//! Bounding volume hierarchy (branch `simperf7`): the packets traverse a binary BVH over the
//! primitives instead of walking the grid (`scene/bvh.rs`: binned surface area heuristic, 12 bins on
//! each axis, spans over 8192 primitives halved at their centroids' middle, leaves of 2-4 primitives,
//! boxes widened by 1 mm, the scene's primitives reordered to the leaves; `scene/packet.rs`: a stack
//! of nodes, each box slab-tested against the 8 lanes at once, near child first by the sign of the
//! packet's direction along the split axis, a node skipped when no searching lane meets its box before
//! its nearest hit; the exact 8-lane primitive tests of before). The grid stays for single rays
//! (`Scene::cast`: rising and near-vertical rays, relief). Scans bit for bit the same: scan hashes of
//! all five scenarios (30 revolutions), the packet-vs-single-ray and variant tests. Instructions per
//! revolution (callgrind as above, 3 revolutions) grid -> BVH: young corn 13.91M -> 11.52M (-17 %),
//! grown corn 16.09M -> 17.24M (+7 %), young soybean 15.51M -> 12.77M
//! (-18 %), grown soybean 18.41M -> 19.75M (+7 %), curved corn 14.44M -> 11.62M (-20 %); the build as committed
//! (the middle splits for large spans came last) gives grown corn 17.01M, young corn 11.27M. CPU time per
//! revolution (`examples/raycast_cost.rs`, 30 revolutions, 5 runs alternating the binaries, median;
//! load average 13-16 on the 2 cores): young corn 2.06 -> 1.33 ms, grown corn 2.53 -> 2.47 ms, young
//! soybean 2.41 -> 1.60 ms, grown soybean 3.45 -> 3.33 ms, curved corn 2.42 -> 1.38 ms: the traversal
//! runs more instructions a cycle than the grid walk (its branches follow the tree, not a coin flip
//! per cell reference). `croprow bench --json` `sim_realtime_factor` (grown corn, wall time at load
//! average 13-15, 4 runs alternating, median) 14.1 -> 14.3: unchanged within the noise. Building the
//! hierarchy adds to the field's generation (CPU time, same load): grown corn 0.26 -> 0.65 s, young
//! corn 0.09 -> 0.29 s, grown soybean 0.50 -> 1.41 s; 3.8G instructions for grown corn, 80 % of them
//! the heuristic's binning.
//! The build as committed, 3 runs alternating (load average 9-12): young corn 2.10 -> 1.26 ms, grown
//! corn 2.40 -> 2.40 ms CPU per revolution.
//!
//! Why the closed canopy gains nothing: a grown-corn revolution visits 312k nodes (~35 instructions
//! each, ~11M) and runs 152k 8-lane patch tests (the grid walk: 26k). A leaf's box bounds its whole
//! primitive, and the boxes of a canopy's leaf segments (15-23 cm, tilted) overlap along the crest
//! that every downward ray skims before it hits; the grid lists a primitive per 10 cm cell with the
//! height range of its part over that cell, which a BVH of whole primitives cannot match. Tried on
//! the branch and dropped (grown corn, instructions per 3 revolutions, against 51.7M):
//! - binning on the widest axis only (half the build time): 58.3M; leaves of 1-2 primitives with it
//!   58.5M;
//! - a node test returning the lanes' nearest entry (a packed minimum) instead of a hit mask: 56.4M;
//!   with it, both children tested at the parent and the nearer visited first: 61.5M (widest-axis
//!   build);
//! - long patches cut into pieces of at most 6 cm, each piece's box a leaf entry (a table of the
//!   primitives a packet tested, as the grid walk had): 64.8M, and a 2 s build;
//! - 32 bins (with an index array for the leaves): 55.7M; the heuristic weighting boxes' top faces
//!   twice (the rays come from above): 51.4M (-0.7 %).
//!
//! Packets of 16 rays (session 20): a laser's rays at 16 consecutive azimuths (3.2°) per packet
//! instead of 8, leaves of 4-8 primitives instead of 2-4 (`LEAF_MIN` 4, `LEAF_MAX` 8, the heuristic's
//! traversal cost 2 primitive tests instead of 1). Scan hashes of all five scenarios the same
//! (`examples/raycast_cost.rs`, 100 revolutions). Instructions per revolution (callgrind, 3
//! revolutions) before -> after: grown corn 17.01M -> 17.41M, young corn 11.27M -> 11.53M; CPU time per
//! revolution (`raycast_cost` 200 revolutions, 4 runs alternating the binaries on an idle machine,
//! ranges): grown corn 1.96-2.02 -> 1.62-1.72 ms, young corn 1.12-1.14 -> 0.94-1.04 ms, grown soybean
//! 2.46-2.60 -> 2.00-2.14 ms; 5 more runs beside a soak (medians): grown corn 2.21 -> 1.86 ms, young
//! corn 1.24 -> 1.08 ms. Half the packets share a node's load and its likely mispredicted branch among
//! twice the rays. `croprow bench --json`, 4 runs alternating on the idle machine: `sim_realtime_factor`
//! 32.6, 34.2, 39.7, 41.9 -> 38.3, 46.3, 46.6, 47.2. Why no traversal order helps: given every ray's
//! final hit as its bound from the start (an oracle for reusing the last revolution's hits), a
//! grown-corn revolution pops 48.2k nodes instead of 50.8k (young corn 26.3k for 26.4k, grown soybean
//! 60.9k for 64.4k; counted with the children-tested-at-the-parent traversal listed below, 16
//! rays): the nodes a packet visits are nearly all ones its rays must cross before they
//! hit. Tried the same session and dropped (grown corn CPU ms per revolution, same scans unless said;
//! single runs are ±10 % on this host):
//! - 32 rays a packet: 1.76 either way (the rays spread too far to share nodes);
//! - tiles of 2 neighbouring lasers × 8 columns instead of one laser × 16 columns: 2.02-2.16 against
//!   1.78-2.10 (5 runs alternating, beside other work);
//! - casting 8 packets' worth of columns laser by laser (consecutive packets side by side in azimuth,
//!   sharing cached nodes): 1.74-1.96 against 1.70-2.02, young corn 1.04-1.18 against 0.98-1.38, within
//!   the noise;
//! - other leaf sizes (max / min / traversal cost): 8/2/1 1.76, 12/6/3 1.68, 16/8/4 1.68, 8/4/4 1.72,
//!   4/2/2 1.84, against 1.64 for 8/4/2;
//! - starting each packet at the deepest node whose box holds the box round all its rays' stretches:
//!   1.64-1.78 against 1.60-1.76 without;
//! - both children tested at the parent, the two siblings in one 64-byte line and a far child tested
//!   again when popped: 1.65-2.24 against 1.73-2.30 (5 runs), within the noise;
//! - stalks tested on all lanes at once instead of lane by lane: 17.4M -> 18.8M instructions with the
//!   above, the time within the noise;
//! - long patches cut into pieces of at most 6 cm, each a leaf entry with a copy of its primitive:
//!   3.5-3.9 ms (a ray tests the same leaf in several pieces), 2× the time;
//! - 32 bins, or the heuristic on spans of any size: within the noise.
//!
//! Session 21: each corn leaf segment (a patch 15-23 cm long) built as two patches of half its
//! length, the same surface (scans differ only in rounding), so that the boxes along the crest are
//! tighter without any primitive tested twice: grown corn 52.36M -> 54.14M instructions for 3
//! revolutions (callgrind as above, +3.4 %). Not merged: smaller boxes along the crest did not take
//! boxes off a ray's way, they added nodes to it.
//!
//! Session 24: beam tiles, primitive first and exact (branch `tiles24`, not merged). The columns go
//! in groups of 192 (38°) from one origin; the hierarchy is walked once per group for the leaves whose
//! boxes meet the group's wedge within a reach of the origin; each primitive's bounding sphere is
//! placed in the sensor's beam and column angles (a polynomial arctangent, 1.5 mrad, with margins)
//! and tested, with the packets' arithmetic, only on the tiles (one laser × 16 columns) it can meet
//! and whose farthest searching lane lies beyond it (walked near side first); a ray whose nearest hit
//! lies inside the reach is final, the rest go on through the hierarchy from the reach's edge. The
//! scans were bit for bit the same (`raycast_cost` hashes), but grown corn cost 25.8M instructions
//! per revolution at a 3 m reach, 31.1M at 5 m, 35.5M at 7 m, against 17.45M for the packets
//! (callgrind as above, 3 revolutions), and 5.1-5.3 ms CPU against 3.1-4.1 (young corn 2.1 against
//! 1.5-1.7; `raycast_cost 30 grown-corn young-corn`, 2 runs of the tiles at 3 m, 4 of main, load
//! 1-2). The first revolution at 3 m: 18.3k primitives walked, 8.3k near a beam, 70.5k tile tests,
//! and 1,107 of the 1,800 tiles still traced; at 7 m 38k, 21k, 65k and 228 (temporary counters). Hidden primitives under a closed canopy are tested anyway: a tile's farthest lane
//! (often one still bound for the ground) keeps most of them in, so the walk pays for the depth of
//! the canopy that a near-first traversal never enters.

use criterion::{Criterion, criterion_group, criterion_main};
use croprow_core::Pose2;
use croprow_sim::{BodyPose, Field, Lidar, ScanBuffer, Scenario};

fn revolution(c: &mut Criterion) {
    let mut group = c.benchmark_group("lidar_revolution");
    for name in ["young-corn", "grown-corn", "young-soybean", "grown-soybean", "curved-corn"] {
        let s = Scenario::builtin(name).expect("built-in scenario");
        let field = Field::generate(&s.field, s.seed).expect("valid field");
        let mut lidar = Lidar::new(&s.lidar, 1).expect("valid lidar");
        let mut scan = ScanBuffer::default();
        let lane = s.lane();
        // Step along the lane between iterations so caches see a moving robot, as in a run.
        let mut x = 20.0;
        group.bench_function(name, |b| {
            b.iter(|| {
                x = if x > 180.0 { 20.0 } else { x + 0.08 };
                let pose = Pose2::new(x, field.lane_y(lane, x), field.row_heading(x));
                lidar.scan(&field, &BodyPose::planar(pose), &mut scan);
                scan.points.len()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, revolution);
criterion_main!(benches);
