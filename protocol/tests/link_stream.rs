//! The live player (a stream's): fed the keyframes of a stimulus one by one, it plays
//! exactly what the stored player plays; without them it reports an underrun.

use touch_protocol::{
    stimulus, DeviceConfig, Limits, LiveParams, Player, Status, Stimulus, Thermal,
};

fn keyframes(n: usize) -> Vec<[i16; 8]> {
    (0..n)
        .map(|i| {
            let mut k = [0i16; 8];
            for (c, v) in k.iter_mut().enumerate() {
                *v = ((i as i32 * 2500 * (c as i32 + 1)) % 30000 - 15000) as i16;
            }
            k
        })
        .collect()
}

const BUILDER: stimulus::Builder<'static> = stimulus::Builder::new("s", 20)
    .ramp_ms(30)
    .layout("test", 1);

#[test]
fn a_live_player_fed_in_time_plays_the_stored_codes() {
    let ks = keyframes(12);
    let file = BUILDER.encode(&ks).unwrap();
    let s = Stimulus::decode(&file).unwrap();
    let device = DeviceConfig::default();
    let stored: Vec<_> = Player::new(&s, &device)
        .take(s.duration_ms() as usize + 1)
        .collect();
    let params = LiveParams {
        keyframe_period_ms: 20,
        ramp_ms: 30,
        full_scale_ma: 1000,
        limits: Limits::SLEEVE,
    };
    let mut live = Player::live(&params, ks[0], ks[1], &device, Thermal::COLD);
    let mut next = 2;
    for (t, want) in stored.iter().enumerate() {
        if live.wants_keyframe() && next < ks.len() {
            live.push_keyframe(ks[next]).unwrap();
            next += 1;
        }
        assert!(live.push_keyframe([0; 8]).is_err() || next >= ks.len());
        let got = live.tick();
        assert_eq!(got.codes, want.codes, "tick {t}");
        assert!(!live.underrun(), "tick {t}");
    }
    // Nothing more comes: the next boundary is an underrun.
    for _ in 0..40 {
        live.tick();
    }
    assert!(live.underrun());
    live.stop();
    let st: Vec<_> = (0..200).map(|_| live.tick()).collect();
    assert!(
        st.iter().any(|t| t.status == Status::Finished),
        "{:?}",
        &st[..3]
    );
}

#[test]
fn a_stored_player_takes_no_keyframes() {
    let ks = keyframes(3);
    let file = BUILDER.encode(&ks).unwrap();
    let mut p = Player::new(&Stimulus::decode(&file).unwrap(), &DeviceConfig::default());
    assert!(!p.wants_keyframe());
    assert_eq!(p.push_keyframe([1; 8]), Err([1; 8]));
}
