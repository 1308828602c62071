fn main() {
    for p in fissure::mesh::phantom::Preset::ALL {
        let ph = fissure::mesh::phantom::generate(p).unwrap();
        let (lo, hi) = ph.mesh.bounding_box();
        println!("{} bbox {:?} {:?}\n{:#?}", p.name(), lo * 1e3, hi * 1e3, ph.landmarks);
    }
}
