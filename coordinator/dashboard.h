// Dashboard: the coordinator's web page and the JSON/PNG endpoints it polls, served on
// `irfarm-coordinator --http ADDR` (service/http_server.h). Plain HTML and a little JavaScript
// (dashboard_page.cc), no build step:
//   GET  /                          the page
//   GET  /api/jobs                  ListJobs as JSON (protobuf's JSON mapping: tilesDone, ...)
//   GET  /api/workers               GetCluster as JSON
//   GET  /api/image.png?job=ID      the job's image so far, tone-mapped PNG (finished tiles), the
//                                   film's size up to 1024 px (block means beyond)
//   GET  /api/record_map.png?job=ID where the job's records were computed, one colour per worker
//                                   (record_map.h), the film's size up to 1024 px
//   POST /api/cancel?job=ID         cancel a job
//   POST /api/priority?job=ID&priority=P   re-prioritise a queued or running job
// The API authenticates like the gRPC job API: `Authorization: Bearer <client token>` (the page
// asks for the token and keeps it in the tab's sessionStorage) and a client sees and acts on its
// own jobs only; with no client tokens configured everything is open (loopback). POSTs must
// carry the header `X-Irfarm-Request: 1`, which an HTML form on another site cannot send (no
// cross-site request forgery against an open loopback coordinator). Errors: the gRPC code's
// HTTP equivalent (404, 400, 409, 401, 503) with the reason as text.
#pragma once

#include <vector>

#include "coordinator/auth.h"
#include "coordinator/job_manager.h"
#include "service/http_server.h"

namespace irfarm {

// The page's HTML (with its script and style).
extern const char kDashboardHtml[];

// The routes above; `manager` and `auth` must outlive the server.
std::vector<HttpRoute> DashboardRoutes(JobManager* manager, Authenticator* auth);

}  // namespace irfarm
