#include "web/web_server.hpp"

#include <spdlog/spdlog.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>

namespace odonav::ground {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace {
std::string random_session_id() {
  std::random_device r;
  char buf[17];
  std::snprintf(buf, sizeof buf, "%08x%08x", r(), r());
  return buf;
}
}  // namespace

class WsSession;

class WebServer::Impl {
 public:
  Impl(WebServerOptions options, WebHandlers handlers, const ChannelSet& channels)
      : options_(std::move(options)),
        handlers_(std::move(handlers)),
        channels_(channels),
        acceptor_(ioc_),
        session_id_(random_session_id()) {}

  WebServerOptions options_;
  WebHandlers handlers_;
  const ChannelSet& channels_;
  net::io_context ioc_{1};
  tcp::acceptor acceptor_;
  std::string session_id_;
  std::thread io_thread_;
  std::optional<net::executor_work_guard<net::io_context::executor_type>> work_;

  mutable std::mutex sessions_mutex_;
  std::set<std::shared_ptr<WsSession>> sessions_;
  std::atomic<std::uint64_t> frames_sent_{0}, frames_dropped_{0};

  // The command thread: POST /api/command runs here, one at a time.
  std::mutex command_mutex_;
  std::condition_variable command_cv_;
  std::deque<std::function<void()>> command_jobs_;
  bool stopping_ = false;
  std::thread command_thread_;

  void do_accept();
  void add(const std::shared_ptr<WsSession>& s) {
    std::lock_guard<std::mutex> lock(sessions_mutex_);
    sessions_.insert(s);
  }
  void remove(const std::shared_ptr<WsSession>& s) {
    std::lock_guard<std::mutex> lock(sessions_mutex_);
    sessions_.erase(s);
  }
  void run_command(std::function<void()> job) {
    {
      std::lock_guard<std::mutex> lock(command_mutex_);
      command_jobs_.push_back(std::move(job));
    }
    command_cv_.notify_one();
  }
  void command_loop() {
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock<std::mutex> lock(command_mutex_);
        command_cv_.wait(lock, [&] { return stopping_ || !command_jobs_.empty(); });
        if (stopping_) return;
        job = std::move(command_jobs_.front());
        command_jobs_.pop_front();
      }
      job();
    }
  }
};

// ---- WebSocket: one Foxglove client ----

class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket socket, WebServer::Impl& server) : ws_(std::move(socket)), server_(server) {
    beast::error_code ec;
    auto& s = beast::get_lowest_layer(ws_).socket();
    peer_ = s.remote_endpoint(ec).address().to_string();
    // The kernel's send buffer is part of what a client that stops reading holds: kept modest, so the
    // per-client queue (max_queued_bytes_per_client) is what bounds it and frames are dropped soon.
    s.set_option(net::socket_base::send_buffer_size(256 * 1024), ec);
    s.set_option(tcp::no_delay(true), ec);
  }

  void run(http::request<http::string_body> request, std::string subprotocol) {
    subprotocol_ = subprotocol;
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(1 << 20);  // client messages are small JSON (subscribe, unsubscribe)
    ws_.set_option(websocket::stream_base::decorator([subprotocol](websocket::response_type& res) {
      res.set(http::field::sec_websocket_protocol, subprotocol);
      res.set(http::field::server, "odonav-ground");
    }));
    ws_.async_accept(request, [self = shared_from_this()](beast::error_code ec) { self->on_accept(ec); });
  }

  /// Queues a frame; data frames past the byte limit are dropped. Any thread.
  void enqueue(std::shared_ptr<const std::string> frame, bool binary, bool droppable) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return;
    if (droppable && queued_bytes_ + frame->size() > server_.options_.max_queued_bytes_per_client) {
      if (dropped_++ == 0) spdlog::warn("web: Foxglove client {} does not keep up: dropping its frames", peer_);
      server_.frames_dropped_++;
      return;
    }
    queued_bytes_ += frame->size();
    queue_.push_back({std::move(frame), binary});
    if (!writing_) {
      writing_ = true;
      net::post(ws_.get_executor(), [self = shared_from_this()] { self->write_next(); });
    }
  }
  void send_json(const nlohmann::json& j) { enqueue(std::make_shared<const std::string>(j.dump()), false, false); }

  /// Subscription ids of a channel (any thread).
  std::vector<std::uint32_t> subscriptions_of(std::uint32_t channel) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return subscriptions_.subscriptions_of(channel);
  }
  void remove_channel(std::uint32_t channel) {
    std::lock_guard<std::mutex> lock(mutex_);
    subscriptions_.remove_channel(channel);
  }
  void close() {
    net::post(ws_.get_executor(), [self = shared_from_this()] {
      beast::error_code ec;
      beast::get_lowest_layer(self->ws_).socket().close(ec);
    });
  }

 private:
  struct Frame {
    std::shared_ptr<const std::string> bytes;
    bool binary;
  };

  void on_accept(beast::error_code ec) {
    if (ec) {
      spdlog::info("web: WebSocket handshake with {} failed: {}", peer_, ec.message());
      return;
    }
    spdlog::info("web: Foxglove client {} connected ({})", peer_, subprotocol_);
    auto metadata = server_.options_.metadata;
    metadata["subprotocol"] = subprotocol_;
    send_json(server_info_json(server_.options_.name, server_.session_id_, metadata));
    // Registered before the channel list is taken: a channel added meanwhile is advertised twice at
    // worst (clients replace a channel by id), never missed.
    server_.add(shared_from_this());
    const auto channels = server_.channels_.all();
    if (!channels.empty()) send_json(advertise_json(channels));
    do_read();
  }

  void do_read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

  void on_read(beast::error_code ec) {
    if (ec) {
      finish(ec == websocket::error::closed ? "closed" : ec.message());
      return;
    }
    if (ws_.got_text()) {
      const std::string text = beast::buffers_to_string(buffer_.data());
      std::vector<nlohmann::json> replies;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        replies = subscriptions_.handle_text(text, [this](std::uint32_t id) { return server_.channels_.contains(id); });
      }
      for (const auto& r : replies) send_json(r);
    } else {
      send_json(status_json(1, "binary client messages (clientPublish, service calls) are not supported"));
    }
    buffer_.consume(buffer_.size());
    do_read();
  }

  void write_next() {
    Frame frame;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (queue_.empty() || closed_) {
        writing_ = false;
        return;
      }
      frame = queue_.front();
    }
    ws_.binary(frame.binary);
    ws_.async_write(net::buffer(*frame.bytes), [self = shared_from_this(), frame](beast::error_code ec, std::size_t) {
      self->on_write(ec, frame);
    });
  }

  void on_write(beast::error_code ec, const Frame& frame) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (closed_) return;  // finish() emptied the queue while this write was in flight
      queued_bytes_ -= frame.bytes->size();
      queue_.pop_front();
    }
    if (ec) {
      finish(ec.message());
      return;
    }
    if (frame.binary) server_.frames_sent_++;
    write_next();
  }

  void finish(const std::string& why) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (closed_) return;
      closed_ = true;
      queue_.clear();
      queued_bytes_ = 0;
    }
    spdlog::info("web: Foxglove client {} gone ({}); {} frames dropped for it", peer_, why, dropped_);
    server_.remove(shared_from_this());
  }

  websocket::stream<beast::tcp_stream> ws_;
  WebServer::Impl& server_;
  beast::flat_buffer buffer_;
  std::string peer_, subprotocol_;
  mutable std::mutex mutex_;  // queue, subscriptions, flags: DDS threads and the I/O thread
  std::deque<Frame> queue_;
  std::size_t queued_bytes_ = 0;
  bool writing_ = false;
  bool closed_ = false;
  std::uint64_t dropped_ = 0;
  ClientSubscriptions subscriptions_;
};

// ---- HTTP: the page, its API, and the upgrade to WebSocket ----

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, WebServer::Impl& server) : stream_(std::move(socket)), server_(server) {}

  void run() { do_read(); }

 private:
  void do_read() {
    parser_.emplace();
    parser_->body_limit(64 * 1024);
    stream_.expires_after(std::chrono::seconds(60));
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

  void on_read(beast::error_code ec) {
    if (ec == http::error::end_of_stream || ec == beast::error::timeout) return shutdown();
    if (ec) {
      spdlog::debug("web: HTTP read failed: {}", ec.message());
      return shutdown();
    }
    http::request<http::string_body> request = parser_->release();
    if (websocket::is_upgrade(request)) {
      const auto offered = std::string(request[http::field::sec_websocket_protocol]);
      const auto chosen = choose_subprotocol(offered);
      if (!chosen) {
        HttpReply r{
            400, "text/plain",
            "WebSocket needs the subprotocol foxglove.websocket.v1 or foxglove.sdk.v1 (offered: '" + offered + "')\n"};
        return respond(request, r, false);
      }
      stream_.expires_never();
      std::make_shared<WsSession>(stream_.release_socket(), server_)->run(std::move(request), *chosen);
      return;
    }
    const std::string target(request.target());
    if (request.method() == http::verb::get || request.method() == http::verb::head) {
      HttpReply reply;
      try {
        reply = server_.handlers_.get(target);
      } catch (const std::exception& e) {
        reply = {500, "text/plain", std::string("error: ") + e.what() + "\n"};
      }
      return respond(request, reply, request.keep_alive());
    }
    if (request.method() == http::verb::post && target == "/api/command") {
      const std::string authorization(request[http::field::authorization]);
      auto self = shared_from_this();
      auto shared_request = std::make_shared<http::request<http::string_body>>(std::move(request));
      server_.run_command([self, shared_request, authorization] {
        HttpReply reply;
        try {
          reply = self->server_.handlers_.command(authorization, shared_request->body());
        } catch (const std::exception& e) {
          reply = {500, "application/json", nlohmann::json{{"error", e.what()}}.dump()};
        }
        net::post(self->stream_.get_executor(), [self, shared_request, reply] {
          self->respond(*shared_request, reply, shared_request->keep_alive());
        });
      });
      return;
    }
    respond(request, {405, "text/plain", "method not allowed: GET the page and /api/fleet, POST /api/command\n"},
            request.keep_alive());
  }

  void respond(const http::request<http::string_body>& request, const HttpReply& reply, bool keep_alive) {
    auto res =
        std::make_shared<http::response<http::string_body>>(static_cast<http::status>(reply.status), request.version());
    res->set(http::field::server, "odonav-ground");
    res->set(http::field::content_type, reply.content_type);
    res->set(http::field::cache_control, "no-store");
    // The page is served by this binary and fetches nothing else: a strict policy keeps it that way.
    res->set(
        "Content-Security-Policy",
        "default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; connect-src 'self'");
    res->keep_alive(keep_alive);
    if (request.method() != http::verb::head) res->body() = reply.body;
    res->prepare_payload();
    if (request.method() == http::verb::head) res->content_length(reply.body.size());
    http::async_write(stream_, *res, [self = shared_from_this(), res, keep_alive](beast::error_code ec, std::size_t) {
      if (ec || !keep_alive) return self->shutdown();
      self->do_read();
    });
  }

  void shutdown() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
  }

  beast::tcp_stream stream_;
  WebServer::Impl& server_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
};

void WebServer::Impl::do_accept() {
  acceptor_.async_accept(net::make_strand(ioc_), [this](beast::error_code ec, tcp::socket socket) {
    if (ec) {
      if (ec == net::error::operation_aborted) return;
      spdlog::warn("web: accept failed: {}", ec.message());
    } else {
      std::make_shared<HttpSession>(std::move(socket), *this)->run();
    }
    do_accept();
  });
}

// ---- WebServer ----

WebServer::WebServer(WebServerOptions options, WebHandlers handlers, const ChannelSet& channels)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(handlers), channels)) {
  const std::string where = impl_->options_.bind_address + ":" + std::to_string(impl_->options_.port);
  beast::error_code ec;
  const auto address = net::ip::make_address(impl_->options_.bind_address, ec);
  if (ec)
    throw std::runtime_error("--bind '" + impl_->options_.bind_address + "': not an IP address (" + ec.message() + ")");
  const tcp::endpoint endpoint(address, static_cast<unsigned short>(impl_->options_.port));
  auto& a = impl_->acceptor_;
  if (!a.open(endpoint.protocol(), ec) && !a.set_option(net::socket_base::reuse_address(true), ec) &&
      !a.bind(endpoint, ec) && !a.listen(net::socket_base::max_listen_connections, ec)) {
    port_ = a.local_endpoint().port();
    return;
  }
  throw std::runtime_error("cannot listen on " + where + ": " + ec.message());
}

WebServer::~WebServer() { stop(); }

void WebServer::start() {
  impl_->do_accept();
  impl_->work_.emplace(impl_->ioc_.get_executor());
  impl_->io_thread_ = std::thread([this] { impl_->ioc_.run(); });
  impl_->command_thread_ = std::thread([this] { impl_->command_loop(); });
}

void WebServer::stop() {
  if (!impl_) return;
  {
    std::lock_guard<std::mutex> lock(impl_->command_mutex_);
    impl_->stopping_ = true;
  }
  impl_->command_cv_.notify_all();
  if (impl_->command_thread_.joinable()) impl_->command_thread_.join();
  if (impl_->io_thread_.joinable()) {
    net::post(impl_->ioc_, [this] {
      beast::error_code ec;
      impl_->acceptor_.close(ec);
      std::lock_guard<std::mutex> lock(impl_->sessions_mutex_);
      for (const auto& s : impl_->sessions_) s->close();
    });
    impl_->work_.reset();
    // Sessions end with their sockets; a bounded wait, then the loop is stopped regardless.
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (!impl_->ioc_.stopped() && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    impl_->ioc_.stop();
    impl_->io_thread_.join();
  }
  std::lock_guard<std::mutex> lock(impl_->sessions_mutex_);
  impl_->sessions_.clear();
}

void WebServer::advertise(const std::vector<ChannelInfo>& channels) {
  if (channels.empty()) return;
  const auto text = std::make_shared<const std::string>(advertise_json(channels).dump());
  std::lock_guard<std::mutex> lock(impl_->sessions_mutex_);
  for (const auto& s : impl_->sessions_) s->enqueue(text, false, false);
}

void WebServer::unadvertise(const std::vector<std::uint32_t>& channel_ids) {
  if (channel_ids.empty()) return;
  const auto text = std::make_shared<const std::string>(unadvertise_json(channel_ids).dump());
  std::lock_guard<std::mutex> lock(impl_->sessions_mutex_);
  for (const auto& s : impl_->sessions_) {
    for (auto id : channel_ids) s->remove_channel(id);
    s->enqueue(text, false, false);
  }
}

bool WebServer::subscribed(std::uint32_t channel_id) const {
  std::lock_guard<std::mutex> lock(impl_->sessions_mutex_);
  for (const auto& s : impl_->sessions_)
    if (!s->subscriptions_of(channel_id).empty()) return true;
  return false;
}

void WebServer::publish(std::uint32_t channel_id, std::uint64_t timestamp_ns, const std::uint8_t* data,
                        std::size_t size) {
  std::lock_guard<std::mutex> lock(impl_->sessions_mutex_);
  for (const auto& s : impl_->sessions_)
    for (auto sub : s->subscriptions_of(channel_id))
      s->enqueue(std::make_shared<const std::string>(message_frame(sub, timestamp_ns, data, size)), true, true);
}

WebServer::Stats WebServer::stats() const {
  Stats st;
  {
    std::lock_guard<std::mutex> lock(impl_->sessions_mutex_);
    st.clients = impl_->sessions_.size();
  }
  st.frames_sent = impl_->frames_sent_;
  st.frames_dropped = impl_->frames_dropped_;
  return st;
}

}  // namespace odonav::ground
