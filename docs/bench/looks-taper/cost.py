"""Cost of the tip taper: min of N process_time per frame, variants interleaved, one process (exact, 640x360).

python docs/bench/looks-taper/cost.py [N] [groom ...]; off, the taper built in at the same geometry (tip 0.9999),
on (tip 0, start 0.5), and a plain thinner fiber for comparison."""
import sys, time
sys.path.insert(0, '.')
from app.gl.context import create_headless
from app.gl.shaders import ProgramCache
from app.bench.grooms import make_subject, DEFAULT
hc = create_headless(); ctx = hc.ctx
size = (640, 360)
N = int(sys.argv[1]) if len(sys.argv) > 1 else 7
names = sys.argv[2:] or [DEFAULT, "sintel_hair.tfx"]
for name in names:
    s = make_subject(ctx, ProgramCache(), name, size)
    variants = {"off": s.p, "arith (tip 0.9999)": s.p.replace(**{"strand.tip_width": 0.9999}),
                "on (tip 0, start 0.5)": s.p.replace(**{"strand.tip_width": 0.0, "strand.taper_start": 0.5}),
                "thin (radius x0.6)": s.p.replace(**{"fibers.fiber_radius": s.p["fibers.fiber_radius"] * 0.6})}
    best = {k: 1e30 for k in variants}
    tests = {}
    for k, p in variants.items():
        f = s.renderer.render(p, s.cam, size, outputs=("ids", "cost"), mode="exact")
        tests[k] = (f.cost[..., 0].sum() / max(1, f.hit.sum()), f.hit.mean())
        s.renderer.render(p, s.cam, size, outputs=("draw",), mode="exact"); ctx.finish()
    keys = list(variants)
    for rep in range(N):
        for k in (keys if rep % 2 == 0 else keys[::-1]):
            c0 = time.process_time()
            s.renderer.render(variants[k], s.cam, size, outputs=("draw",), mode="exact")
            ctx.finish()
            best[k] = min(best[k], time.process_time() - c0)
    for k in keys:
        print(f"{name} | {k}: {best[k]*1e3:.1f} ms CPU, x{best[k]/best['off']:.3f}; fiber tests per covered px {tests[k][0]:.1f}, covered {tests[k][1]:.3f}", flush=True)
