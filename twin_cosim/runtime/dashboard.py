"""The live page of ``twin watch --dashboard PORT``: served on 127.0.0.1 only, the gap and the
tracked effects' values per window, the last window's twin against the machine, and the
alarms, updating as windows arrive.

The page is one HTML file with its script inline (no file or library from elsewhere): it asks
``/state.json`` every second and draws SVG charts. The server is the standard library's HTTP
server in a thread of its own, reading the watch's state dictionary (replaced, never changed
in place, by the watch, so a reader never sees half an update).
"""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from twin_cosim.runtime.watch_log import READABLE, plain

LOOPBACK = "127.0.0.1"

PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>twin watch</title>
<style>
body{font:14px system-ui,sans-serif;margin:16px 24px;color:#222;background:#fafafa}
h1{font-size:20px;margin:0 0 4px} .status{color:#555;margin-bottom:12px}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(430px,1fr));gap:14px}
.card{background:#fff;border:1px solid #ddd;border-radius:6px;padding:10px 12px}
.card h2{font-size:14px;margin:0 0 6px} .alarm{color:#b00020;font-weight:600}
table{border-collapse:collapse;width:100%;font-size:13px} td,th{padding:3px 6px;text-align:left}
tr:nth-child(even){background:#f4f4f4} .none{color:#2e7d32}
svg text{font-size:11px;fill:#444} .legend span{margin-right:14px;font-size:12px}
</style></head><body>
<h1>twin watch</h1><div class="status" id="status">waiting for the first window</div>
<div class="card"><h2>Alarms</h2><div id="alarms" class="none">none</div></div><br>
<div class="grid">
<div class="card"><h2>Gap per window (times the noise floor)</h2><div id="gap"></div>
<div class="legend"><span style="color:#777">&#9632; gap to the twin</span>
<span style="color:#e67e00">&#9632; gap the tracked effects leave</span></div></div>
<div class="card"><h2 id="lasttitle">Last window: position, machine and twin</h2>
<div id="lastx"></div><div class="legend"><span style="color:#1f77b4">&#9632; machine</span>
<span style="color:#d62728">&#9632; twin</span></div></div>
<div class="card"><h2>Last window: current, machine and twin</h2><div id="lasti"></div></div>
</div><br><div class="grid" id="effects"></div>
<script>
const READABLE = __READABLE__;
function fmt(v){ if(v===null||v===undefined||!isFinite(v)) return "-";
  const a=Math.abs(v); if(a===0) return "0";
  if(a>=1e-3&&a<1e6){const d=Math.max(0,2-Math.floor(Math.log10(a)));return v.toFixed(d);}
  return v.toExponential(2);}
function scaled(unit){const r=READABLE[unit];return r?r:[1,unit];}
function chart(el, series, opts){
  const W=420,H=170,L=58,R=8,T=8,B=26; let xs=[],ys=[];
  for(const s of series){xs=xs.concat(s.x);ys=ys.concat(s.y.filter(v=>v!==null));}
  if(!xs.length){el.innerHTML="<i>no data yet</i>";return;}
  let x0=Math.min(...xs),x1=Math.max(...xs),y0=Math.min(...ys),y1=Math.max(...ys);
  if(opts.floor!==undefined){y0=Math.min(y0,opts.floor);y1=Math.max(y1,opts.floor);}
  if(x1===x0)x1=x0+1; if(y1===y0){y1=y0+1e-12+Math.abs(y0)*0.01;y0=y0-1e-12-Math.abs(y0)*0.01;}
  const pad=(y1-y0)*0.08; y0-=pad; y1+=pad;
  const px=x=>L+(x-x0)/(x1-x0)*(W-L-R), py=y=>T+(1-(y-y0)/(y1-y0))*(H-T-B);
  let svg=`<svg width="${W}" height="${H}" role="img">`;
  svg+=`<rect x="${L}" y="${T}" width="${W-L-R}" height="${H-T-B}" fill="none" stroke="#ccc"/>`;
  for(let k=0;k<=3;k++){const y=y0+(y1-y0)*k/3;svg+=`<text x="${L-4}" y="${py(y)+4}" text-anchor="end">${fmt(y)}</text>`;
    svg+=`<line x1="${L}" x2="${W-R}" y1="${py(y)}" y2="${py(y)}" stroke="#eee"/>`;}
  for(let k=0;k<=4;k++){const x=x0+(x1-x0)*k/4;svg+=`<text x="${px(x)}" y="${H-8}" text-anchor="middle">${fmt(x)}</text>`;}
  if(opts.xlabel) svg+=`<text x="${W-R}" y="${H-8}" text-anchor="end">${opts.xlabel}</text>`;
  if(opts.floor!==undefined) svg+=`<line x1="${L}" x2="${W-R}" y1="${py(opts.floor)}" y2="${py(opts.floor)}" stroke="#999" stroke-dasharray="3,3"/>`;
  for(const a of (opts.marks||[])) if(a>=x0&&a<=x1) svg+=`<line x1="${px(a)}" x2="${px(a)}" y1="${T}" y2="${H-B}" stroke="#b00020" stroke-width="1.5"/>`;
  for(const s of series){let d="";s.x.forEach((x,i)=>{const y=s.y[i];if(y===null)return;d+=(d?"L":"M")+px(x).toFixed(1)+","+py(y).toFixed(1);});
    svg+=`<path d="${d}" fill="none" stroke="${s.color}" stroke-width="1.4"/>`;
    if(s.dots) s.x.forEach((x,i)=>{if(s.y[i]!==null) svg+=`<circle cx="${px(x)}" cy="${py(s.y[i])}" r="2" fill="${s.color}"/>`;});}
  el.innerHTML=svg+"</svg>";}
async function refresh(){
  let state; try{state=await (await fetch("state.json",{cache:"no-store"})).json();}catch(e){return;}
  const w=state.windows, marks=state.alarms.map(a=>a.window);
  document.getElementById("status").textContent=(w.length?`${w.length} windows checked; last: window ${w[w.length-1].window} (Sequence ${w[w.length-1].sequence}), real-time factor ${fmt(w[w.length-1].real_time_factor)}. `:"")+(state.status||"");
  const al=document.getElementById("alarms");
  if(state.alarms.length){al.className="";al.innerHTML="<table>"+state.alarms.map(a=>`<tr><td class="alarm">window ${a.window}</td><td>${a.text.replace(/^drift alarm at [^:]*: /,"")}${a.diagnosis&&!a.diagnosis.failed?`<br>diagnosis: ${a.diagnosis.effect||"no effect accepted"}, held-out gap ${fmt(a.diagnosis.gap_before)} &rarr; ${fmt(a.diagnosis.gap_after)} &times; noise floor`:""}</td></tr>`).join("")+"</table>";}
  chart(document.getElementById("gap"),[{x:w.map(v=>v.window),y:w.map(v=>v.gap),color:"#777",dots:true},
    {x:w.filter(v=>v.unexplained!==null).map(v=>v.window),y:w.filter(v=>v.unexplained!==null).map(v=>v.unexplained),color:"#e67e00",dots:true}],{floor:1,marks:marks,xlabel:"window"});
  const last=state.last; if(last){
    document.getElementById("lasttitle").textContent=`Last window (${last.window}): position, machine and twin`;
    chart(document.getElementById("lastx"),[{x:last.t,y:last.position.map(v=>v*1e3),color:"#1f77b4"},{x:last.t,y:last.twin_position.map(v=>v*1e3),color:"#d62728"}],{xlabel:"s   [mm]"});
    chart(document.getElementById("lasti"),[{x:last.t,y:last.current,color:"#1f77b4"},{x:last.t,y:last.twin_current,color:"#d62728"}],{xlabel:"s   [A]"});}
  const units=state.units||{}; const names=Object.keys(units).filter(n=>n!=="unexplained");
  const box=document.getElementById("effects");
  if(box.children.length!==names.length) box.innerHTML=names.map((n,i)=>`<div class="card"><h2>${n} [${scaled(units[n])[1]}]</h2><div id="e${i}"></div></div>`).join("");
  names.forEach((n,i)=>{const f=scaled(units[n])[0]; const t=w.filter(v=>v.values&&v.values[n]!==undefined);
    chart(document.getElementById("e"+i),[{x:t.map(v=>v.window),y:t.map(v=>v.values[n]*f),color:"#1f77b4",dots:true}],{marks:marks,xlabel:"window"});});
}
refresh(); setInterval(refresh,1000);
</script></body></html>
"""


class Dashboard:
    """The live page's HTTP server on 127.0.0.1.

    Parameters
    ----------
    port
        TCP port.
    state
        The watch's state: ``windows`` (per window: ``window``, ``sequence``,
        ``real_time_factor``, ``gap``, ``unexplained``, ``values``), ``alarms`` (their log
        lines), ``last`` (the last window's ``t``, ``position``, ``twin_position``,
        ``current``, ``twin_current``), ``units``, ``status``.
    """

    def __init__(self, port: int, state: dict[str, Any]) -> None:
        self.state = state
        page = PAGE.replace("__READABLE__", json.dumps(READABLE)).encode()
        owner = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 - the standard library's name
                if self.path in ("/", "/index.html"):
                    body, kind = page, "text/html; charset=utf-8"
                elif self.path.startswith("/state.json"):
                    body, kind = json.dumps(plain(owner.state)).encode(), "application/json"
                else:
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, format: str, *args: Any) -> None:
                return  # the watch's output is its own

        try:
            self.server = ThreadingHTTPServer((LOOPBACK, port), Handler)
        except OSError as exc:
            raise OSError(f"--dashboard {port}: cannot listen on {LOOPBACK} ({exc})") from None
        self.server.daemon_threads = True
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://{LOOPBACK}:{self.server.server_address[1]}/"

    def start(self) -> None:
        """Serve in a thread of its own."""
        self._thread.start()

    def stop(self) -> None:
        """Stop serving."""
        self.server.shutdown()
        self.server.server_close()
