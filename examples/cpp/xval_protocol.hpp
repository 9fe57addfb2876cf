// xval_protocol.hpp: speak xval's process protocol v1 (docs/protocol.md) from C++17.
//
// One header, standard library only. xval writes one JSON document to the
// program's stdin; the program writes CSV to stdout. This header reads the
// document into an xval::Problem and writes the rows:
//
//     #include "xval_protocol.hpp"
//
//     int main() {
//         return xval::run([](const xval::Problem& problem, xval::Output& out) {
//             std::vector<xval::Vec3> q = problem.positions(), v = problem.velocities();
//             out.row(0, q, v);                         // step 0: the initial state
//             out.clock.start();                        // time only the stepping loop
//             for (long step = 1; step <= problem.steps; ++step) {
//                 my_step(q, v, problem.dt);
//                 if (out.wants(step)) out.row(step, q, v);   // row() pauses the clock
//             }
//             out.clock.stop();
//         });
//     }
//
// Units are SI, the frame is xval's scene frame (right-handed, gravity along
// -z). A constraint's force is the force it exerts on its first particle
// (Pin: `particle`; Rod: `a`), in N. An exception thrown inside run() is
// printed as one stderr line and the program exits with code 1, which xval
// reports as `failed` with that line; throw xval::Unsupported for a scene the
// solver cannot express (exit code 77: xval reports the case `skipped`).
#pragma once

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <iterator>
#include <map>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

namespace xval {

constexpr int PROTOCOL_VERSION = 1;

struct Error : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// Thrown for a scene the solver cannot express: run() exits with UNSUPPORTED_EXIT_CODE and the message
// on stderr, and xval records the case as `skipped` with that reason (never as a failure of the solver).
struct Unsupported : Error {
    using Error::Error;
};

constexpr int UNSUPPORTED_EXIT_CODE = 77;

// ---------------------------------------------------------------------------------------------
// Vectors

struct Vec3 {
    double x = 0, y = 0, z = 0;
};
inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
inline Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
inline Vec3 operator*(Vec3 a, double s) { return s * a; }
inline Vec3 operator/(Vec3 a, double s) { return {a.x / s, a.y / s, a.z / s}; }
inline Vec3& operator+=(Vec3& a, Vec3 b) { return a = a + b; }
inline Vec3& operator-=(Vec3& a, Vec3 b) { return a = a - b; }
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline double norm(Vec3 a) { return std::sqrt(dot(a, a)); }

// ---------------------------------------------------------------------------------------------
// A small JSON reader (enough for the document: objects, arrays, numbers, strings, true/false/null)

class Json {
public:
    enum class Kind { Null, Bool, Number, String, Array, Object };

    Kind kind = Kind::Null;
    bool boolean = false;
    double number = 0;
    std::string string;
    std::vector<Json> items;                             // Array
    std::vector<std::pair<std::string, Json>> members;   // Object, in document order

    static Json parse(const std::string& text) {
        std::size_t at = 0;
        Json value = parse_value(text, at);
        skip_space(text, at);
        if (at != text.size()) fail(text, at, "text after the document");
        return value;
    }

    bool has(const std::string& key) const { return find(key) != nullptr; }

    const Json& operator[](const std::string& key) const {
        const Json* found = find(key);
        if (!found) throw Error("document: missing field '" + key + "'");
        return *found;
    }
    const Json& operator[](std::size_t index) const { return items.at(index); }

    double as_number(const std::string& what) const {
        if (kind != Kind::Number) throw Error(what + ": expected a number");
        return number;
    }
    long as_integer(const std::string& what) const {
        double value = as_number(what);
        if (value != std::floor(value)) throw Error(what + ": expected an integer");
        return static_cast<long>(value);
    }
    const std::string& as_string(const std::string& what) const {
        if (kind != Kind::String) throw Error(what + ": expected a string");
        return string;
    }
    Vec3 as_vec3(const std::string& what) const {
        if (kind != Kind::Array || items.size() != 3) throw Error(what + ": expected three numbers");
        return {items[0].as_number(what), items[1].as_number(what), items[2].as_number(what)};
    }

private:
    const Json* find(const std::string& key) const {
        for (const auto& member : members)
            if (member.first == key) return &member.second;
        return nullptr;
    }

    [[noreturn]] static void fail(const std::string& text, std::size_t at, const std::string& what) {
        throw Error("document: bad JSON at byte " + std::to_string(at) + " (" + what + ")" +
                    (at < text.size() ? std::string(": '") + text[at] + "'" : std::string(": at the end")));
    }
    static void skip_space(const std::string& text, std::size_t& at) {
        while (at < text.size() && (text[at] == ' ' || text[at] == '\n' || text[at] == '\r' || text[at] == '\t')) ++at;
    }
    static void expect(const std::string& text, std::size_t& at, const char* word) {
        for (const char* c = word; *c; ++c, ++at)
            if (at >= text.size() || text[at] != *c) fail(text, at, std::string("expected ") + word);
    }
    static std::string parse_string(const std::string& text, std::size_t& at) {
        std::string out;
        ++at;  // the opening quote
        while (at < text.size() && text[at] != '"') {
            char c = text[at++];
            if (c != '\\') {
                out += c;
                continue;
            }
            if (at >= text.size()) fail(text, at, "unfinished escape");
            char e = text[at++];
            switch (e) {
                case 'n': out += '\n'; break;
                case 't': out += '\t'; break;
                case 'r': out += '\r'; break;
                case 'b': out += '\b'; break;
                case 'f': out += '\f'; break;
                case 'u': {
                    if (at + 4 > text.size()) fail(text, at, "short \\u escape");
                    unsigned code = static_cast<unsigned>(std::stoul(text.substr(at, 4), nullptr, 16));
                    at += 4;
                    if (code < 0x80) {
                        out += static_cast<char>(code);
                    } else if (code < 0x800) {
                        out += static_cast<char>(0xC0 | (code >> 6));
                        out += static_cast<char>(0x80 | (code & 0x3F));
                    } else {  // (surrogate pairs are passed through as two 3-byte sequences)
                        out += static_cast<char>(0xE0 | (code >> 12));
                        out += static_cast<char>(0x80 | ((code >> 6) & 0x3F));
                        out += static_cast<char>(0x80 | (code & 0x3F));
                    }
                    break;
                }
                default: out += e;  // \" \\ \/
            }
        }
        if (at >= text.size()) fail(text, at, "unterminated string");
        ++at;  // the closing quote
        return out;
    }
    static Json parse_value(const std::string& text, std::size_t& at) {
        skip_space(text, at);
        if (at >= text.size()) fail(text, at, "expected a value");
        Json value;
        char c = text[at];
        if (c == '{') {
            value.kind = Kind::Object;
            ++at;
            skip_space(text, at);
            if (at < text.size() && text[at] == '}') { ++at; return value; }
            while (true) {
                skip_space(text, at);
                if (at >= text.size() || text[at] != '"') fail(text, at, "expected a key");
                std::string key = parse_string(text, at);
                skip_space(text, at);
                expect(text, at, ":");
                value.members.emplace_back(std::move(key), parse_value(text, at));
                skip_space(text, at);
                if (at < text.size() && text[at] == ',') { ++at; continue; }
                expect(text, at, "}");
                return value;
            }
        }
        if (c == '[') {
            value.kind = Kind::Array;
            ++at;
            skip_space(text, at);
            if (at < text.size() && text[at] == ']') { ++at; return value; }
            while (true) {
                value.items.push_back(parse_value(text, at));
                skip_space(text, at);
                if (at < text.size() && text[at] == ',') { ++at; continue; }
                expect(text, at, "]");
                return value;
            }
        }
        if (c == '"') {
            value.kind = Kind::String;
            value.string = parse_string(text, at);
            return value;
        }
        if (c == 't') { expect(text, at, "true"); value.kind = Kind::Bool; value.boolean = true; return value; }
        if (c == 'f') { expect(text, at, "false"); value.kind = Kind::Bool; return value; }
        if (c == 'n') { expect(text, at, "null"); return value; }
        const char* start = text.c_str() + at;
        char* end = nullptr;
        value.number = std::strtod(start, &end);
        if (end == start) fail(text, at, "expected a value");
        value.kind = Kind::Number;
        at += static_cast<std::size_t>(end - start);
        return value;
    }
};

// ---------------------------------------------------------------------------------------------
// The problem xval asks for

struct Particle {
    double mass;
    Vec3 position, velocity;
};

struct Constraint {
    std::string kind;   // "pin", "rod", "line" or "ellipse"
    int particle = -1;  // pin, line, ellipse: the particle
    Vec3 anchor;        // pin: the fixed point, m
    int a = -1, b = -1; // rod: the two particles
    double length = 0;  // pin, rod: m
    Vec3 point, direction;         // line: a point on it (m) and its direction (any nonzero length)
    Vec3 centre;                   // ellipse: its centre, m (the wire lies in the x-z plane through it)
    double semi_x = 0, semi_z = 0; // ellipse: semi-axes along x and z, m
    int first() const { return kind == "rod" ? a : particle; }  // the particle its force is reported on
};

struct Problem {
    std::string scene_name;
    std::vector<Particle> particles;
    std::vector<Constraint> constraints;
    Vec3 gravity;               // m/s^2
    double duration = 0;        // s
    double dt = 0;              // s
    long steps = 0;             // steps to take
    std::vector<long> sample_steps;  // the steps to write a row for (0 first, `steps` last)
    Json options;               // the suite's `options`, passed through
    Json document;              // everything xval sent

    std::vector<Vec3> positions() const {
        std::vector<Vec3> out;
        for (const auto& p : particles) out.push_back(p.position);
        return out;
    }
    std::vector<Vec3> velocities() const {
        std::vector<Vec3> out;
        for (const auto& p : particles) out.push_back(p.velocity);
        return out;
    }
    // An option's value as a number / string, or `fallback` when the suite did not set it.
    double option(const std::string& name, double fallback) const {
        return options.has(name) ? options[name].as_number("options." + name) : fallback;
    }
    std::string option(const std::string& name, const std::string& fallback) const {
        return options.has(name) ? options[name].as_string("options." + name) : fallback;
    }
};

inline Problem read_problem(std::istream& in = std::cin) {
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    Problem p;
    p.document = Json::parse(text);
    const Json& doc = p.document;
    long version = doc["protocol"].as_integer("protocol");
    if (version != PROTOCOL_VERSION)
        throw Error("document: protocol " + std::to_string(version) + ", this helper speaks " +
                    std::to_string(PROTOCOL_VERSION));
    const Json& scene = doc["scene"];
    p.scene_name = scene["name"].as_string("scene.name");
    for (std::size_t i = 0; i < scene["particles"].items.size(); ++i) {
        const Json& q = scene["particles"][i];
        std::string where = "scene.particles[" + std::to_string(i) + "]";
        p.particles.push_back({q["mass"].as_number(where + ".mass"), q["position"].as_vec3(where + ".position"),
                               q["velocity"].as_vec3(where + ".velocity")});
    }
    for (std::size_t k = 0; k < scene["constraints"].items.size(); ++k) {
        const Json& c = scene["constraints"][k];
        std::string where = "scene.constraints[" + std::to_string(k) + "]";
        Constraint out;
        out.kind = c["kind"].as_string(where + ".kind");
        if (out.kind == "pin") {
            out.particle = static_cast<int>(c["particle"].as_integer(where + ".particle"));
            out.anchor = c["anchor"].as_vec3(where + ".anchor");
            out.length = c["length"].as_number(where + ".length");
        } else if (out.kind == "rod") {
            out.a = static_cast<int>(c["a"].as_integer(where + ".a"));
            out.b = static_cast<int>(c["b"].as_integer(where + ".b"));
            out.length = c["length"].as_number(where + ".length");
        } else if (out.kind == "line") {
            out.particle = static_cast<int>(c["particle"].as_integer(where + ".particle"));
            out.point = c["point"].as_vec3(where + ".point");
            out.direction = c["direction"].as_vec3(where + ".direction");
        } else if (out.kind == "ellipse") {
            out.particle = static_cast<int>(c["particle"].as_integer(where + ".particle"));
            out.centre = c["centre"].as_vec3(where + ".centre");
            out.semi_x = c["semi_x"].as_number(where + ".semi_x");
            out.semi_z = c["semi_z"].as_number(where + ".semi_z");
        } else {  // a kind newer than this helper: the solver cannot express the scene
            throw Unsupported(where + ": constraint kind '" + out.kind + "' is not one this helper knows");
        }
        p.constraints.push_back(out);
    }
    p.gravity = scene["gravity"].as_vec3("scene.gravity");
    p.duration = scene["duration"].as_number("scene.duration");
    p.dt = doc["dt"].as_number("dt");
    p.steps = doc["steps"].as_integer("steps");
    for (const Json& s : doc["sample_steps"].items) p.sample_steps.push_back(s.as_integer("sample_steps"));
    if (doc.has("options")) p.options = doc["options"];
    return p;
}

// ---------------------------------------------------------------------------------------------
// Timing and output

// Accumulates the wall time between start() and stop() calls, in seconds.
class Clock {
public:
    void start() { started_ = std::chrono::steady_clock::now(); running_ = true; }
    void stop() {
        if (running_) seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
        running_ = false;
    }
    bool running() const { return running_; }
    double seconds() const { return seconds_; }

private:
    std::chrono::steady_clock::time_point started_;
    double seconds_ = 0;
    bool running_ = false;
};

// Collects the rows (header first) and writes them, with `# wall_time` and `# version`, when finished.
class Output {
public:
    Clock clock;  // the stepping loop's time: written as `# wall_time`

    // forces: whether rows carry f{k}_x,f{k}_y,f{k}_z for every constraint.
    Output(const Problem& problem, bool forces, std::string version = "")
        : n_particles_(problem.particles.size()), n_constraints_(problem.constraints.size()),
          forces_(forces), dt_(problem.dt), version_(std::move(version)),
          wanted_(problem.sample_steps.begin(), problem.sample_steps.end()) {
        text_.reserve(problem.sample_steps.size() * (1 + 6 * n_particles_ + 3 * n_constraints_) * 24);
        text_ += "t";
        for (std::size_t i = 0; i < n_particles_; ++i)
            for (const char* s : {"p", "v"})
                for (const char* axis : {"x", "y", "z"}) text_ += "," + std::string(s) + std::to_string(i) + "_" + axis;
        if (forces_)
            for (std::size_t k = 0; k < n_constraints_; ++k)
                for (const char* axis : {"x", "y", "z"}) text_ += ",f" + std::to_string(k) + "_" + axis;
        text_ += "\n";
    }

    bool wants(long step) const { return wanted_.count(step) != 0; }

    // One row: the state after `step` steps (q, v: one Vec3 per particle; f: one per constraint, when forces).
    void row(long step, const std::vector<Vec3>& q, const std::vector<Vec3>& v, const std::vector<Vec3>* f = nullptr) {
        bool was_running = clock.running();
        clock.stop();  // recording is not stepping
        if (q.size() != n_particles_ || v.size() != n_particles_) throw Error("row: one position and velocity per particle");
        number(static_cast<double>(step) * dt_);
        for (std::size_t i = 0; i < n_particles_; ++i) {
            vec(q[i]);
            vec(v[i]);
        }
        if (forces_) {
            if (!f || f->size() != n_constraints_) throw Error("row: one force per constraint");
            for (const Vec3& force : *f) vec(force);
        }
        text_ += "\n";
        if (was_running) clock.start();
    }

    void finish(std::ostream& out = std::cout) {
        clock.stop();
        char line[64];
        std::snprintf(line, sizeof line, "# wall_time = %.17g\n", clock.seconds());
        out << line;
        if (!version_.empty()) out << "# version = " << version_ << "\n";
        out << text_;
        out.flush();
    }

private:
    void number(double x) {
        char buffer[32];
        int n = std::snprintf(buffer, sizeof buffer, "%.17g", x);
        if (text_.back() != '\n') text_ += ',';
        text_.append(buffer, static_cast<std::size_t>(n));
    }
    void vec(Vec3 a) { number(a.x); number(a.y); number(a.z); }

    std::size_t n_particles_, n_constraints_;
    bool forces_;
    double dt_;
    std::string version_;
    std::unordered_set<long> wanted_;
    std::string text_;
};

// Read the document, call `solve(problem, output)`, write the output. An exception is one stderr line and
// exit code 1 (xval: `failed`), or UNSUPPORTED_EXIT_CODE for xval::Unsupported (xval: `skipped`).
// forces: whether the rows carry constraint forces; version: written as `# version`.
inline int run(const std::function<void(const Problem&, Output&)>& solve, bool forces = false,
               const std::string& version = "", const char* program = "solver") {
    try {
        std::ios::sync_with_stdio(false);
        Problem problem = read_problem(std::cin);
        Output output(problem, forces, version);
        solve(problem, output);
        output.finish(std::cout);
        return 0;
    } catch (const Unsupported& error) {
        std::cerr << program << ": " << error.what() << std::endl;
        return UNSUPPORTED_EXIT_CODE;
    } catch (const std::exception& error) {
        std::cerr << program << ": " << error.what() << std::endl;
        return 1;
    }
}

}  // namespace xval
