# Generates mitsuba_bsdf.rs: PYTHONPATH=<unpacked mitsuba 3.9.1 + drjit 1.5.0 wheels> python3.11 mitsuba_bsdf.py
# Reference values from Mitsuba 3.9.1 (scalar_rgb) for raylume's bsdf.rs tests.
import math, random, mitsuba as mi, drjit as dr
mi.set_variant('scalar_rgb')
random.seed(7)

def d(theta, phi):
    t, p = math.radians(theta), math.radians(phi)
    return [math.sin(t)*math.cos(p), math.sin(t)*math.sin(p), math.cos(t)]

def pairs(transmission=False, narrow=False):
    out = []
    for ti in [0.0, 30.0, 60.0, 80.0, 88.0]:
        wi = d(ti, 0.0)
        mirror = [-wi[0], -wi[1], wi[2]]
        cands = [d(ti + 5, 180.0), d(max(ti - 10, 0), 170.0), d(45, 90), d(10, 200)]
        if narrow:
            for e in [0.5, 1.5, 3.0]:
                cands.append(d(ti + e if ti + e < 89.5 else ti - e, 180.0 + e))
        for _ in range(3):
            cands.append(d(random.uniform(0, 89), random.uniform(0, 360)))
        if transmission:
            for c in list(cands):
                cands.append([c[0], c[1], -c[2]])
            # near the refracted direction for eta 1.5
            st = math.sin(math.radians(ti)) / 1.5
            cands.append([-st, 0.0, -math.sqrt(1 - st*st)])
        for c in cands:
            out.append((wi, c))
    return out

def evals(bsdf, prs):
    rows = []
    ctx = mi.BSDFContext()
    for wi, wo in prs:
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(wi)
        val, pdf = bsdf.eval_pdf(ctx, si, mi.Vector3f(wo))
        rows.append((wi, wo, [val[0], val[1], val[2]], pdf))
    return rows

def num(x):
    s = '%.9g' % float(x)
    if not any(c in s for c in '.en'):
        s += '.0'
    return s

def fmt(v):
    return '[' + ', '.join(num(x) for x in v) + ']'

def emit(name, rows):
    print('const %s: &[Ref] = &[' % name)
    for wi, wo, val, pdf in rows:
        print('    (%s, %s, %s, %s),' % (fmt(wi), fmt(wo), fmt(val), num(pdf)))
    print('];')

albedo = [0.2, 0.5, 0.8]
for name, mat, alpha in [('ROUGHCONDUCTOR_CU_030', 'Cu', 0.3), ('ROUGHCONDUCTOR_AU_005', 'Au', 0.05)]:
    b = mi.load_dict({'type': 'roughconductor', 'material': mat, 'distribution': 'ggx', 'alpha': alpha})
    emit(name, evals(b, pairs(narrow=alpha < 0.1)))
b = mi.load_dict({'type': 'roughconductor', 'distribution': 'ggx', 'alpha': 0.5, 'specular_reflectance': {'type': 'rgb', 'value': [0.9, 0.6, 0.3]}})
emit('ROUGHCONDUCTOR_NONE_050', evals(b, pairs()))
b = mi.load_dict({'type': 'plastic', 'int_ior': 1.5, 'ext_ior': 1.0, 'diffuse_reflectance': {'type': 'rgb', 'value': albedo}})
emit('PLASTIC_15', evals(b, pairs()))
for a in [0.05, 0.15, 0.3]:
    b = mi.load_dict({'type': 'roughplastic', 'int_ior': 1.5, 'ext_ior': 1.0, 'alpha': a, 'distribution': 'ggx', 'nonlinear': False,
                      'diffuse_reflectance': {'type': 'rgb', 'value': albedo}})
    emit('ROUGHPLASTIC_15_%03d' % int(round(a * 100)), evals(b, pairs(narrow=a < 0.1)))
for a in [0.1, 0.4]:
    b = mi.load_dict({'type': 'roughdielectric', 'int_ior': 1.5, 'ext_ior': 1.0, 'alpha': a, 'distribution': 'ggx'})
    prs = pairs(transmission=True)
    emit('ROUGHDIELECTRIC_15_%03d_OUTSIDE' % int(round(a * 100)), evals(b, prs))
    inside = [([wi[0], wi[1], -wi[2]], [wo[0], wo[1], -wo[2]]) for wi, wo in prs]
    emit('ROUGHDIELECTRIC_15_%03d_INSIDE' % int(round(a * 100)), evals(b, inside))

# Delta lobes: the sampled weight of the smooth conductor and of the smooth plastic's coat.
print('const SMOOTH_SAMPLES: &[(&str, f32, [f32; 3], f32)] = &[')
ctx = mi.BSDFContext()
for label, b in [('conductor Cu', mi.load_dict({'type': 'conductor', 'material': 'Cu'})),
                 ('conductor Al', mi.load_dict({'type': 'conductor', 'material': 'Al'})),
                 ('plastic 1.5', mi.load_dict({'type': 'plastic', 'int_ior': 1.5, 'ext_ior': 1.0, 'diffuse_reflectance': {'type': 'rgb', 'value': albedo}}))]:
    for ti in [0.0, 30.0, 60.0, 80.0, 89.0]:
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(d(ti, 0.0))
        bs, w = b.sample(ctx, si, 0.0, mi.Point2f(0.5, 0.5))
        print('    ("%s", %s, %s, %s),' % (label, num(math.cos(math.radians(ti))), fmt([w[0], w[1], w[2]]), num(bs.pdf)))
print('];')
