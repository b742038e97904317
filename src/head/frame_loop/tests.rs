use super::health;

#[test]
fn the_status_is_running_with_frames_error_once_the_source_fails_and_idle_before_any() {
    assert_eq!(health(true, false, true), Some(true));
    assert_eq!(health(false, false, true), Some(false), "silent");
    assert_eq!(health(true, true, true), Some(false), "failed");
    assert_eq!(health(false, true, false), Some(false), "failed first");
    assert_eq!(
        health(false, false, false),
        None,
        "waiting for the first frame"
    );
}
