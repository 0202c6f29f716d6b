"""The figures of `make bench` and their targets: one table, for bench/run.py
(which measures them) and bench/readme_table.py (which shows them in
README.md); docs/benchmarks.md says what each key means."""

# key -> (target, "higher"/"lower" is better, unit/explanation)
TARGETS = {
    "replay_throughput_cpp_MBps": (None, "higher", "MB/s, timing=none, 64 KiB reads"),
    "replay_vs_cat_ratio": (0.8, "higher", "C++ replay time vs cat, same file"),
    "replay_python_vs_cat_ratio": (0.25, "higher", "Python replay vs cat"),
    "replay_rss_MB_100MiB": (None, "lower", "MiB peak RSS, 100 MiB session"),
    "replay_rss_MB_1GiB": (None, "lower", "MiB peak RSS, 1 GiB session"),
    "timing_session_p50_us": (20, "lower", "µs late, median"),
    "timing_session_p99_us": (200, "lower", "µs late, 99th percentile"),
    "timing_session_drift_pct": (0.1, "lower", "% over 10 s"),
    "naive_player_drift_pct": (None, "info", "% over 10 s (reference)"),
    "record_throughput_ratio": (0.9, "higher", "recorded / unrecorded TCP"),
    "record_latency_ratio": (1.1, "lower", "recorded / unrecorded RTT"),
    "record_rss_MB_1GiB": (None, "lower", "MiB peak RSS recording 1 GiB"),
    "pty_proxy_vs_socat_cpu_ratio": (1.0, "lower", "record --pty CPU s/MB / socat's"),
    "pty_proxy_vs_socat_latency_p99_ratio": (1.0, "lower", "record --pty one-way p99 / socat's"),
    "tcp_proxy_vs_socat_cpu_ratio": (1.0, "lower", "record --listen CPU s/MB / socat's"),
    "tcp_proxy_vs_socat_latency_p99_ratio": (1.0, "lower", "record --listen one-way p99 / socat's"),
    "udp_proxy_loss_pct": (None, "info", "% of datagrams lost through record --udp"),
    "udp_socat_loss_pct": (None, "info", "% lost through socat's UDP relay"),
    "udp_proxy_vs_socat_delivered_ratio": (1.0, "higher", "record --udp / socat, delivered"),
    "udp_proxy_datagrams_sent": (None, "info", "datagrams sent through record --udp"),
    "udp_proxy_datagrams_received": (None, "info", "of them, received by the device"),
    "udp_proxy_datagrams_lost": (None, "info", "of them, lost"),
    "udp_socat_datagrams_sent": (None, "info", "datagrams sent through socat"),
    "udp_socat_datagrams_received": (None, "info", "of them, received by the device"),
    "udp_socat_datagrams_lost": (None, "info", "of them, lost"),
    "reserial_replay_s": (None, "info", "s, 10,000 exchanges, pytest-reserial"),
    "wiretape_pyserial_replay_s": (None, "info", "s, same, wiretape:// URL"),
    "wiretape_vs_reserial_time_ratio": (0.5, "lower", "wiretape time / reserial"),
    # --- show (issue 26): 10 MB shown with colour and Δt, vs show's loop before ---
    "show_sensor_s": (0.5, "lower", "show run, colour, 10 MB: 13 B requests, 1 KiB replies"),
    "show_bulk_s": (0.5, "lower", "show run, colour, 10 MB of 4 KiB rx records"),
    "show_vs_anchor_ratio": (None, "info", "show's loop now / before issue 26, sensor session"),
    # --- diff (issue 38): exchanges aligned, vs diff by position before it ---
    "diff_aligned_vs_anchor_ratio": (2.0, "lower",
                                     "diff of two 100k-exchange sessions, aligned / by position, CPU s"),
    "diff_aligned_s": (None, "info", "diff, 100k exchanges, a handshake before one of them"),
    "diff_worst_s": (None, "info", "diff, 100k exchanges, every reply different"),
    # --- fault campaigns (docs/faults.md) ---
    "faults_campaign_vs_loop_ratio": (1.3, "lower", "campaign / same faulty replays in a loop"),
    # Info: faulty runs also wait for what the driver does about each fault.
    "faults_campaign_vs_clean_ratio": (None, "info", "campaign / as many clean replays"),
    "faults_jobs2_speedup": (1.8, "higher", "campaign --jobs 1 time / --jobs 2 time"),
    "faults_inert_vs_clean_ratio": (1.3, "lower", "replays with faults= firing none / clean"),
    # --- --speed K (docs/replay.md, "Faster than real time") ---
    "speed_campaign_speedup": (5.0, "higher", "Hokuyo campaign --speed 1 time / --speed 10"),
    "speed_campaign_same_outcomes": (1, "higher", "1: --speed 10 gives --speed 1's outcomes"),
    "request_vs_sequence_time_ratio": (1.5, "lower",
                                       "match=request / match=sequence, 100,000 exchanges"),
    "modbus_reordering_vs_sequence_time_ratio": (2.0, "lower",
                                                 "profile=modbus-tcp reordering / sequence"),
    "request_rss_MB_1GiB": (64, "lower", "MiB peak RSS, match=request, 1 GiB session"),
    # --- wiretape view (docs/view.md) ---
    "view_first_paint_ms_100k": (2000, "lower", "ms to first paint, 100,000 records, Chromium"),
    "view_write_s_100k": (None, "info", "s to write that page"),
    "view_page_MB_100k": (None, "info", "MB, that page"),
    # --- the --as shim (docs/replay.md, "Serial lines under --as") ---
    "shim_redirected_write_added_ns": (2000, "lower",
                                       "ns a 1-byte write to the redirected pty gains"),
    "shim_redirected_read_added_ns": (2000, "lower",
                                      "ns a 1-byte read of the redirected pty gains"),
    "shim_unrelated_call_added_ns": (100, "lower",
                                     "ns an unrelated write/dup/close gains (worst)"),
    "shim_redirected_write_ratio": (None, "info", "with the shim / without, redirected write"),
    # --- sessions of several ports (issue 25, docs/replay.md "Several channels") ---
    "channel_replay_time_ratio": (2.0, "lower",
                                  "1 channel of a 4-channel file / same data alone, time"),
    "channel_replay_rss_ratio": (1.1, "lower", "same, peak RSS"),
    "causal_cross_channel_p99_extra_us": (50, "lower",
                                          "µs p99 write->rx across channels minus on one"),
    "record_4_channels_vs_4_single_cpu_ratio": (1.1, "lower",
                                                "record of 4 channels CPU s/MB / 4 single-port "
                                                "records of the same traffic"),
}
