mod cp_support;
use morphoid::cp;

#[test]
#[ignore]
fn quick_look() {
    let Some(dir) = cp_support::data_dir() else {
        return;
    };
    let names = cp_support::tooth_names(&dir);
    let params = cp::CpParams::default();
    let t0 = std::time::Instant::now();
    let preps: Vec<cp::Prepared> = names
        .iter()
        .take(6)
        .map(|n| {
            let m = cp_support::load_tooth(&dir, n);
            let p = cp::prepare(&m, &params.prepare).expect("prepare");
            println!(
                "{n}: feats {:?} reor {} dens {:?}",
                p.features().len(),
                p.reoriented(),
                p.features()
                    .iter()
                    .map(|&f| p.density()[f as usize])
                    .collect::<Vec<_>>()
            );
            p
        })
        .collect();
    println!("prepare {:?}", t0.elapsed() / 6);
    let t0 = std::time::Instant::now();
    for i in 0..6 {
        for j in 0..6 {
            let c = cp::compare(&preps[i], &preps[j], &params.compare);
            print!("{:.4}{} ", c.distance, if c.reflected { "r" } else { " " });
        }
        println!();
    }
    println!("compare {:?}", t0.elapsed() / 36);
}
