# Directional albedo (mean sample weight) of Mitsuba 3's principled for irfarm's bsdf_test.
import sys, numpy as np, mitsuba as mi, drjit as dr
mi.set_variant('llvm_ad_rgb')
cases = {
 'A': {'type':'principled','base_color':{'type':'rgb','value':[0.8,0.5,0.2]},'roughness':0.4},
 'B': {'type':'principled','base_color':{'type':'rgb','value':[0.9,0.6,0.3]},'roughness':0.3,'metallic':1.0,'anisotropic':0.5},
 'C': {'type':'principled','base_color':{'type':'rgb','value':[0.9,0.9,0.7]},'roughness':0.3,'spec_trans':0.7,'eta':1.5},
 'D': {'type':'principled','base_color':{'type':'rgb','value':[0.2,0.6,0.8]},'roughness':0.6,'clearcoat':1.0,'clearcoat_gloss':0.5,
       'sheen':0.5,'sheen_tint':0.5,'spec_tint':0.5,'flatness':0.3,'specular':0.7,'metallic':0.2},
}
N = 400000
for name, d in cases.items():
    b = mi.load_dict(d)
    out = []
    for side in (1, -1):
        for th in (0.5, 30, 60, 85):
            t = np.radians(th)
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wi = mi.Vector3f(float(np.sin(t)), 0.0, float(side*np.cos(t)))
            si.n = mi.Normal3f(0,0,1); si.sh_frame = mi.Frame3f(si.n)
            sampler = mi.load_dict({'type':'independent'}); sampler.seed(7, N)
            ctx = mi.BSDFContext()
            bs, w = b.sample(ctx, si, sampler.next_1d(), sampler.next_2d())
            w = np.array(w)
            w[~np.isfinite(w)] = 0
            out.append((side, th, w.mean(axis=1) if w.shape[0]==3 else w.mean(axis=0)))
    for side, th, m in out:
        print(name, side, th, ' '.join('%.5f' % x for x in m))
