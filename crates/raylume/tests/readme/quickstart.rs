use raylume::glam::Vec3;
use raylume::scene::Material;
use raylume::{Backend, SceneBuilder, Tracer};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A floor, a box and a ball under a square lamp.
    let mut b = SceneBuilder::new();
    b.look_at(Vec3::new(0.0, 1.5, 5.0), Vec3::new(0.0, 0.6, 0.0), 40.0)
        .size(160, 120)
        .spp(16);
    let white = b.material(Material::diffuse("white", Vec3::splat(0.75)));
    let red = b.material(Material::diffuse("red", Vec3::new(0.8, 0.1, 0.1)));
    let lamp = b.material(Material::emissive("lamp", Vec3::splat(15.0)));
    let (x, z) = (Vec3::X, Vec3::Z);
    b.quad(Vec3::new(-3.0, 0.0, 3.0), 6.0 * x, -6.0 * z, white) // faces up: x * -z = +y
        .cuboid(Vec3::new(-1.2, 0.0, -0.4), Vec3::new(-0.4, 0.8, 0.4), red)
        .sphere(Vec3::new(0.7, 0.5, 0.0), 0.5, white)
        .quad(Vec3::new(-0.5, 3.0, -0.5), x, z, lamp); // faces down: x * z = -y
    let scene = b.build()?; // validated as a scene file is

    let render = Tracer::new(Backend::Cpu).render(&scene)?;
    let s = &render.stats;
    println!("{} spp in {:.2} s on {}", s.spp, s.seconds.total, s.adapter);
    let path = std::env::temp_dir().join("raylume-quickstart.png");
    render.save(&path)?;

    // 8-bit sRGB, the PNG's own pixels: row-major, top row first.
    let rgb8: Vec<[u8; 3]> = render.to_srgb8()?;
    let png = raylume::image::open(&path)?.into_rgb8();
    assert_eq!(png.as_raw(), &rgb8.concat());
    assert!(rgb8.iter().any(|p| p[0] > 128), "the lamp lights the scene");
    Ok(())
}
