"""The pages of ``mechsim bench --streaming`` (``streaming.md``): the summary against the
targets, then one section per measurement, from the result ``run_streaming`` measured."""

from __future__ import annotations

from typing import Any

from mechsim.bench.startup import VARIANTS

#: The stages of a recorded sample whose wall time is split out.
STAGES = ("integrate", "evaluate", "encode", "publish", "diagnostics", "write")


def report_lines(result: dict[str, Any], duration: float) -> list[str]:
    """The lines of ``streaming.md``."""
    return (_summary(result) + _live_lines(result) + _recording_lines(result, duration)
            + _realtime_lines(result) + _startup_lines(result) + _latency_lines(result))


def _verdict(value: float, target: float, at_least: bool = True) -> str:
    return "met" if (value >= target if at_least else value <= target) else "**missed**"


def _summary(r: dict[str, Any]) -> list[str]:
    t = r["targets"]
    py = [x for x in r["batches"]["pendulum"] if x["consumer"] == "python"][0]
    every = min(r["batches"]["systems"], key=lambda x: x["rtf"])
    rec = min(r["recording"], key=lambda x: x["rtf"])
    one = [x for x in r["startup"]["one_process"] if x["variant"] == "overlapped"]
    largest = max(one, key=lambda x: x["instances"])
    h = r["host"]
    return ["# Streaming throughput", "",
            f"Every figure below was measured in one run of `mechsim bench --streaming` on "
            f"{h['cores']} cores (load average at the end {h['loadavg'][0]:.1f}); real-time "
            f"factor = simulated seconds / wall seconds.", "",
            "| target | measured | |", "|---|---|---|",
            f"| a Python subscriber in another process gets every sample of a fast pendulum "
            f"run through `<ns>/sample_batch` at ≥ {t['batch_pendulum']:g}× | "
            f"{py['rtf']:.0f}× (every sample: {'yes' if py['every_sample'] else 'no'}) | "
            f"{_verdict(py['rtf'], t['batch_pendulum'])} |",
            f"| the same for every system at ≥ {t['batch_every_system']:g}× | slowest "
            f"{every['rtf']:.0f}× ({every['system']}) | "
            f"{_verdict(every['rtf'], t['batch_every_system'])} |",
            f"| recording at ≥ {t['recording']:g}× for every system | slowest "
            f"{rec['rtf']:.0f}× ({rec['system']}; fastest of {len(rec.get('runs', [0]))} "
            f"recordings, median {rec.get('median_rtf', rec['rtf']):.0f}×) | "
            f"{_verdict(rec['rtf'], t['recording'])} |",
            f"| start-up of a {largest['instances']}-instance scene ≤ {t['startup_100']:g} s | "
            f"{largest['startup_s']:.2f} s | "
            f"{_verdict(largest['startup_s'], t['startup_100'], at_least=False)} |", ""]


def _live_lines(r: dict[str, Any]) -> list[str]:
    b = r["batches"]
    lines = ["## Live consumers in another process", "",
             "A fast `--lossless` run (no recording) with one consumer in a new process; "
             "real-time factor from the first sample to the last one the consumer took. "
             "Per-sample topics: one subscription per streamed topic (`state`, `energy`, "
             "`invariants`, `observables`, `/tf`, ... as the system has them). Batch topic: "
             "`<ns>/sample_batch` alone, the Python consumer "
             "`mechsim.ros.batches.subscribe_batches` "
             "(every message decoded into numpy columns). The C consumer is written against "
             "rcl alone (`src/mechsim/bench/rcl_subscriber.c`, serialized messages taken in "
             "one wait set), compiled in the run"
             + ("." if b["c_consumer"] == "built" else f": not built here ({b['c_consumer']}).")
             + " The ceiling beside each: a bare rclpy loop that simulates nothing sends the "
             "same messages (per-sample: one recorded payload of each topic as many times as "
             "the run sent it; batches: a full recorded batch as often as the run's samples "
             "need), with the same slices in flight as `--lossless`, to a new consumer of the "
             "same kind.", "",
             "| system | topics | consumer | simulated [s] | real-time factor | bare rclpy "
             "loop (ceiling) | every sample arrived |", "|---|---|---|---|---|---|---|"]
    for x in r["live"]:
        lines.append(f"| {x['system']} | per-sample | {x['subscriber']} | {x['sim_s']:g} | "
                     f"{x['rtf']:.0f} | {x['bare_rtf']:.0f} | "
                     + ("yes" if x["every_message"] else f"no ({x['lost']} lost)") + " |")
    for x in b["pendulum"]:
        lines.append(f"| {x['system']} | batch | {x['consumer']} | {x['sim_s']:g} | "
                     f"{x['rtf']:.0f} | {x['bare']['rtf']:.0f} | "
                     + ("yes" if x["every_sample"] else "no") + " |")
    lines += ["", "The batch topic for every system, Python consumer "
              f"({b['systems'][0]['sim_s']:g} s simulated each):" if b["systems"] else "", "",
              "| system | real-time factor | samples | messages | every sample arrived |",
              "|---|---|---|---|---|"]
    for x in sorted(b["systems"], key=lambda x: x["rtf"]):
        lines.append(f"| {x['system']} | {x['rtf']:.0f} | {x['samples']} | {x['messages']} | "
                     + ("yes" if x["every_sample"] else "no") + " |")
    return lines + [""]


def _recording_lines(r: dict[str, Any], duration: float) -> list[str]:
    lines = ["## Recording", "",
             f"Recording at 100 Hz output, as fast as possible, bag writer attached "
             f"({duration:g} s simulated per system; real-time factor = simulated / wall "
             f"seconds after start-up, to the bag complete on disk): the fastest of "
             f"{len(r['recording'][0].get('runs', [0]))} recordings (timeit's convention: a "
             "slower one met other work on the host), made in rounds (every system once a "
             "round, so a slow stretch of the host meets one recording of several systems), "
             "then the median and every one's. "
             "Reference loop: the host's speed before each recording, the ms a fixed "
             "pure-Python loop took (`mechsim.bench.host`; lower is faster).", "",
             "Per-sample cost split of the fastest recording, µs of wall time per sample in "
             "each stage (write runs in the bag writer's thread, alongside the others).", "",
             "| system | real-time factor | median (each) | reference loop, ms | µs per sample | "
             + " | ".join(STAGES) + " | messages |",
             "|---|---|---|---|---|" + "---|" * len(STAGES) + "---|"]
    for x in sorted(r["recording"], key=lambda x: x["rtf"]):
        split = x["split_us"]
        ref = ", ".join(f"{v:.2f}" for v in x.get("reference_ms", []))
        lines.append(f"| {x['system']} | {x['rtf']:.0f} | {x.get('median_rtf', x['rtf']):.0f} "
                     f"({_runs(x.get('runs', []))}) | {ref} | {x['us_per_sample']:.1f} | "
                     + " | ".join(f"{split.get(k, 0.0):.1f}" for k in STAGES)
                     + f" | {x['messages']} |")
    variants = r.get("recording_variants") or []
    if variants:
        from mechsim.bench.recording_designs import DESIGNS

        names = [n for n in DESIGNS if n in variants[0]["designs"]]
        lines += ["", "The slowest systems without events recorded again with each design of a "
                  "recording in turn (`mechsim.bench.recording_designs`): next block integrated "
                  "meanwhile = each block's successor integrated on a thread of its own while "
                  "the block is released (`SystemRun.integrates_ahead`); a process of their own "
                  "= the chunks' layout, compression, checksum and write in a child process, "
                  "out of reach of the recording process's interpreter lock; dropped = rows "
                  "encoded and handed to the writer thread, then dropped, the ceiling of any "
                  "bag writer behind these nodes. Median real-time factor; every run's in "
                  "brackets:", "",
                  "| system | " + " | ".join(DESIGNS[n] for n in names) + " |",
                  "|---|" + "---|" * len(names)]
        for v in variants:
            cells = [f"{v['designs'][n]['median']:.0f} ({_runs(v['designs'][n]['runs'])})"
                     for n in names]
            lines.append(f"| {v['system']} | " + " | ".join(cells) + " |")
    return lines + [""]


def _runs(values: list[float]) -> str:
    return ", ".join(f"{v:.0f}" for v in values)


def _realtime_lines(r: dict[str, Any]) -> list[str]:
    cpu, rec = r["realtime_all"], r["realtime_all_recording"]
    return ["## Real time", "",
            f"All {cpu['systems']} systems streaming together in real time at 100 Hz (one "
            f"process, {cpu['sim_s']:g} s): CPU share {cpu['cpu_share_run']:.2f} of one core "
            f"after start-up ({cpu['cpu_share_total']:.2f} with the {cpu['startup_s']:.2f} s "
            f"start-up), {cpu['samples']} samples; with a bag and a Rerun recording: "
            f"{rec['cpu_share_run']:.2f} of one core.", ""]


def _startup_lines(r: dict[str, Any]) -> list[str]:
    st = r["startup"]
    lines = ["## Start-up of scenes of many instances", "",
             "A scene of N pendulums in one process (`run_scene`, as `mechsim run` runs it, "
             "kernels warm): seconds from the call to the first sample. The graph check's "
             "discovery window (one name, one node) runs while the nodes are made; they "
             "publish and serve nothing until it passed. For the largest scene, the design "
             "variants beside it, each the median of starts made in turn (every start's "
             "seconds in brackets). A scene's nodes make the services that serve their "
             "parameters (`ros2 param`) once the first samples are out: the last column is "
             "when every node serves them.", "",
             "| instances | design | graph check | start-up [s] | every node serving its "
             "parameters [s] |", "|---|---|---|---|---|"]
    for x in st["one_process"]:
        starts = (" (" + ", ".join(f"{s:.2f}" for s in x["starts_s"]) + ")"
                  if "starts_s" in x else "")
        served = x.get("parameters_served_s")
        lines.append(f"| {x['instances']} | {VARIANTS[x['variant']]} | "
                     f"{'yes' if x['graph_check'] else 'no'} | {x['startup_s']:.2f}{starts} | "
                     f"{'—' if served is None else f'{served:.2f}'} |")
    prof = st["profile"]
    lines += ["", f"Where the start-up of {prof['instances']} goes (a profiled start, "
              f"{prof['startup_s']:.2f} s with the profiler; seconds inside each call, all "
              "calls together; rclpy's `Node()` makes its parameter and type-description "
              "services with `create_service`, counted in both rows):", "",
              "| call | seconds |", "|---|---|"]
    for name, secs in sorted(prof["profile_s"].items(), key=lambda kv: -kv[1]):
        lines.append(f"| {name} | {secs:.2f} |")
    n = max(x["instances"] for x in st["one_process"])
    lines += ["", f"The same endpoints made by bare rclpy, {n} nodes of a simulator node's "
              f"{st['publishers_per_node']} publishers, one subscription and three services of "
              "its own, in new processes (imports not counted unless said):", "",
              "| variant | processes | seconds |", "|---|---|---|"]
    names = {"node": "a node per instance, as mechsim makes them",
             "no_rclpy_services": "a node per instance without the parameter and "
             "type-description services rclpy adds",
             "no_type_description": "a node per instance without rclpy's type-description "
             "service",
             "one_node": "one node carrying every instance's endpoints"}
    for x in st["bare"]:
        extra = (f" (launch to the last process ready, imports included: "
                 f"{x['launch_to_ready_s']:.2f} s)" if "launch_to_ready_s" in x else "")
        lines.append(f"| {names[x['variant']]} | {x['processes']} | {x['seconds']:.2f}"
                     f"{extra} |")
    sp = st["split"]
    lines += ["", f"The scene split: {sp['instances']} pendulums as {sp['processes']} "
              f"processes of `run_scene` started together (no graph check: every share "
              f"publishes /clock, which the check refuses as a second clock), launch to the "
              f"last one's first sample, Python, rclpy and the models' start included: "
              f"{sp['launch_to_first_sample_s']:.2f} s."]
    pm = st.get("processes_mode")
    if pm is not None and "failed" in pm:
        lines += ["", f"One process per node (`mechsim run --processes`, graph check included), "
                  f"{pm['instances']} pendulums: the run failed ({pm['failed']})."]
    elif pm is not None:
        lines += ["", f"One process per node (`mechsim run --processes`, graph check included), "
                  f"{pm['instances']} pendulums: {pm['call_to_end_s']:.2f} s from the call to "
                  f"the last process ended; the slowest process's own start-up (its imports "
                  f"not counted) {pm['slowest_process_startup_s']:.2f} s."]
    return [*lines, ""]


def _latency_lines(r: dict[str, Any]) -> list[str]:
    latency = r["first_message_s"]
    lines = ["## First message", "",
             "Launch of `mechsim run pendulum` in a new process to its first /clock message "
             "here (warm kernel cache): "
             + ", ".join(f"{x:.2f} s" for x in latency["warm_pendulum_s"]) + ".", "",
             "Cold start (the model not derived yet, the shared loops compiled by set-up) "
             "against the two runs after it:", "",
             "| system | first message, cold [s] | warm [s] | cold / warm |",
             "|---|---|---|---|"]
    for x in latency["cold"]:
        cold_s = "—" if x["cold_s"] is None else f"{x['cold_s']:.2f}"
        ratio = "—" if x["ratio"] is None else f"{x['ratio']:.2f}"
        lines.append(f"| {x['system']} | {cold_s} | "
                     + ", ".join(f"{v:.2f}" for v in x["warm_s"]) + f" | {ratio} |")
    return lines
