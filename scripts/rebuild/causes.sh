#!/usr/bin/env bash
# Rebuilds the results page's "Falls of every cause" figures (docs/results.md) from a fresh clone:
# for each robot and controller, development and held-out runs of every cause (pushes, trips,
# slips, steps, failing motors: generate --causes), long undisturbed walks, a randomised second
# sampler with another mix and (the G1 under Unitree's policy) pushes only in the ambiguous band;
# the models made on every cause (train's default rule: the 95 % Wilson upper bound of the
# cross-validated FPR within the budget, folds grouped by cause and impulse band), each shipped
# model before (pushes only) and after on every set, the leave-one-cause-out study and the
# budget study; then the tables (scripts/rebuild/cause_table.py). About 4 h on 2 cores, of which
# 10 h of simulated walking (generation and features) is half.
#   scripts/rebuild/causes.sh OUT_DIR      (DATA=dir of datasets to reuse, JOBS=2)
source "$(dirname "$0")/common.sh"
MIX=push:0.4,trip:0.15,slip:0.15,step:0.15,fault:0.15
# The ASIMO-like robot: only steps fell it of the new causes (trips, slips and faults do not:
# the profile's ranges), which stay in its mix for the false alarms they may raise.
ASIMO_MIX=push:0.5,step:0.2,trip:0.1,slip:0.1,fault:0.1
gen() { local out=$1; shift; $FP generate "$@" --jobs "$JOBS" --out "$DATA/$out" --json > "$OUT/generate_$out.json"; }

# -- the G1 under Unitree's policy (MuJoCo) --------------------------------------------------------
gen g1pol_mix_dev1000 --robot g1_12dof --causes $MIX --trajectories 1000 --seed 5711
gen g1pol_mix_test600 --robot g1_12dof --causes $MIX --trajectories 600 --seed 5712
gen g1pol_mix_rand300 --robot g1_12dof --causes push:0.2,trip:0.2,slip:0.2,step:0.2,fault:0.2 \
  --randomize --trajectories 300 --seed 5713
# The ambiguous band (20-80 % of pushes fell) of the policy's pushes, 38.6-63.3 N s: forces of
# 386-633 N for 0.1 s.
gen g1pol_ambiguous400 --robot g1_12dof --push-force-n 386,633 --trajectories 400 --seed 5714
gen g1pol_walk10h --robot g1_12dof --causes walk --walk-s 600 --trajectories 60 --seed 7001
# -- the G1 and the ASIMO-like robot under C_bal (PyBullet) ----------------------------------------
gen g1cbal_mix_dev400 --robot g1 --sensor-noise 1 --causes $MIX --trajectories 400 --seed 5721
gen g1cbal_mix_test200 --robot g1 --sensor-noise 1 --causes $MIX --trajectories 200 --seed 5722
gen g1cbal_walk20m --robot g1 --sensor-noise 1 --causes walk --walk-s 600 --trajectories 2 --seed 7002
gen asimo_mix_dev400 --robot asimo_like --sensor-noise 1 --causes $ASIMO_MIX --trajectories 400 --seed 5731
gen asimo_mix_test200 --robot asimo_like --sensor-noise 1 --causes $ASIMO_MIX --trajectories 200 --seed 5732
gen asimo_walk20m --robot asimo_like --sensor-noise 1 --causes walk --walk-s 600 --trajectories 2 --seed 7003
