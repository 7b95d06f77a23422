//! CI's smoke run of `examples/load.rs`: 8 keep-alive clients for 3 s against `lightport serve`
//! (the page, scenes.json, an ~8 MB bundle gzip and plain) and 4 slow clients dripping bytes:
//! no errors, every route answered, each slow client cut off by the server's 2 s head timeout,
//! and the server's memory bounded. The numbers are printed, never asserted.

use lightport::load;

#[test]
fn the_server_under_load_answers_everything_in_bounded_memory() {
    let options = load::Options { exe: env!("CARGO_BIN_EXE_lightport").into(), clients: 8, seconds: 3.0, slow: 4 };
    let report = load::run(&options).unwrap_or_else(|e| panic!("{e:#}"));
    load::print(&report, &options);
    assert!(report.errors.is_empty(), "errors: {:?}", report.errors);
    for (label, latencies, _) in &report.routes {
        assert!(!latencies.is_empty(), "no {label} answered");
    }
    assert_eq!(report.slow_cut_off, options.slow, "every slow client is cut off");
    // Everything served is precomputed at start; under load only connection buffers and the
    // responses in flight (8 clients, at most one ~8 MB bundle each) are added.
    let added = report.peak_rss.saturating_sub(report.start_rss);
    assert!(added < 128 << 20, "the server grew by {} MB under load", added >> 20);
}
