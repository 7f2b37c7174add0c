// Throwaway diagnostic: distribution of ROI line contributions to M0+.
use ohd::experiment::Silent;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let text = std::fs::read_to_string(&args[1]).unwrap();
    let sets: Vec<String> = args[2..].to_vec();
    let (_, exp) = ohd::config::load(&text, &args[1], &sets).unwrap();
    let out = exp.run(&Silent);
    let n = exp.plan.samples() as f64;
    for roi in 0..2u32 {
        let mut c: Vec<(f64, u8, f64)> = out.lines.iter().filter(|l| l.roi == roi)
            .map(|l| { let f = l.frequency.abs(); let inb = if (6e3..=18.3e3).contains(&f) {1.0} else {0.0}; (l.weight * inb, l.class, l.frequency) }).collect();
        c.sort_by(|a, b| b.0.partial_cmp(&a.0).unwrap());
        let tot: f64 = c.iter().map(|x| x.0).sum();
        let tot2: f64 = c.iter().map(|x| x.0 * x.0).sum();
        let nz = c.iter().filter(|x| x.0 > 0.0).count();
        println!("roi {roi}: lines {} in-band {} sum {:.3e} rel.err(iid) {:.2}", c.len(), nz, tot / n, (tot2).sqrt() / tot);
        let mut acc = 0.0;
        for (k, x) in c.iter().take(10).enumerate() { acc += x.0; println!("  top{k}: w {:.3e} class {} f {:.0} cum {:.2}", x.0, x.1, x.2, acc / tot); }
        let by_class: Vec<f64> = (0..3).map(|k| c.iter().filter(|x| x.1 == k).map(|x| x.0).sum::<f64>() / tot).collect();
        println!("  class shares {:?}", by_class);
    }
}
