"""Prints Mitsuba 3's own RGB for the spectra of spectrum_test.cc (the expected values there):
each spectrum is put where the test puts it (a diffuse reflectance, a conductor's eta, an area
emitter's radiance) and read back with mi.traverse. pip install mitsuba (3.9.1 was used)."""
import mitsuba as mi

mi.set_variant("scalar_rgb")
CASES = [("reflectance", "0.5"), ("reflectance", "400:0.1, 500:0.5, 600:0.7, 700:0.9"),
         ("reflectance", "400:0.5, 700:0.5"), ("eta", "400:1.5, 700:2.5"),
         ("radiance", "1"), ("radiance", "0.3"), ("radiance", "400:0, 500:8, 600:15.6, 700:18.4"),
         ("radiance", "400:1, 700:1"), ("radiance", "550:5, 560:5"),
         ("reflectance", "380:0.05, 450:0.8, 520:0.2, 610:0.6, 780:0.3")]
for i, (name, value) in enumerate(CASES):
    if name == "radiance":
        inner = '<emitter type="area"><spectrum name="radiance" value="%s"/></emitter>' % value
    elif name == "eta":
        inner = '<bsdf type="conductor"><spectrum name="eta" value="%s"/></bsdf>' % value
    else:
        inner = '<bsdf type="diffuse"><spectrum name="reflectance" value="%s"/></bsdf>' % value
    scene = mi.load_string('<scene version="3.0.0"><shape type="sphere" id="s">%s</shape></scene>'
                           % inner)
    params = mi.traverse(scene)
    key = [k for k in params.keys() if k.endswith(name + ".value")][0]
    v = params[key]
    rgb = [float(v)] * 3 if isinstance(v, float) else [float(c) for c in v]
    print('{"%s", "%s", {%.6g, %.6g, %.6g}},' % (name, value, *rgb))
