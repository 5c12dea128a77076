//! Several jobs at once: higher priority first, and jobs of equal priority taking turns.

use super::*;

#[tokio::test]
async fn higher_priority_first_then_equal_jobs_take_turns() {
    let f = farm(None);
    // Two jobs of two tiles each at priority 0, then one of one tile at priority 5.
    let a = submit(&f, 16, 8, 8).await;
    let b = submit(&f, 16, 8, 8).await;
    let c = submit_with(&f, 8, 8, 8, |s| s.priority = 5).await;
    assert_eq!(job_status(&f.app, c).await.priority, 5);
    let mut order = Vec::new();
    while let Some(l) = lease(&f.app, "w").await {
        order.push(l.job);
        let frame = if l.job == c { (8, 8) } else { (16, 8) };
        let (status, _) = upload(&f.app, l.lease, exr(&tile_of(&l, frame, 1.0))).await;
        assert_eq!(status, StatusCode::OK);
    }
    assert_eq!(order, [c, a, b, a, b], "priority first, then turns");
}
