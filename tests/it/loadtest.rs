//! The load generator against the real service (health scenario: the domain
//! routes are exercised by their own tests).

use std::time::Duration;

use bmc_irradiance::loadtest::{LoadTestOptions, Scenario, run};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_scenario_reports_only_successes_and_server_memory() {
    let app = crate::common::spawn_app().await;
    let options = LoadTestOptions {
        url: app.base.clone(),
        clients: 4,
        duration: Duration::from_millis(300),
        scenario: Scenario::Health,
        scene: "unused".into(),
        points_per_request: 1,
        samples: 1,
        tile_size: 1,
        // The server runs in this process, so its RSS is ours.
        server_pid: Some(std::process::id()),
    };
    let report = run(&options).await.unwrap();
    assert!(report.requests > 0);
    assert_eq!(report.ok, report.requests);
    assert_eq!(report.errors(), 0);
    assert_eq!(report.overloaded, 0);
    assert!(report.latency.p50_ms <= report.latency.p99_ms);
    assert!(report.latency.p99_ms <= report.latency.max_ms);
    let rss = report.server_rss.unwrap();
    assert!(rss.start_kib > 0 && rss.max_kib >= rss.end_kib);
}
