// Conformance harness: ticks a tree in BehaviorTree.CPP 4.10 and prints its trace.
//
// Links against an installed BehaviorTree.CPP (see README.md); contains none of its code.
//
//   conformance_harness trace TREE.xml          -> the golden trace on stdout
//   conformance_harness stubs MANIFEST TREE.xml -> load TREE.xml with every node of MANIFEST
//                                                  registered as a stub leaf, tick it
//
// The tree file's first comment configures the run:
//   <!-- conformance ticks=5 period_ms=0 bb=x,y -->
// Leaves are <Scripted name="A" results="S,R,F"/>: tick k returns the k-th result (the last
// repeats); S = SUCCESS, F = FAILURE, R = RUNNING. Every tick and halt of a Scripted leaf is an
// event. Per root tick the trace is
//   tick N STATUS
//     A S            (leaf A ticked, returned SUCCESS)
//     A halt         (leaf A halted while RUNNING)
//   bb x=3           (root blackboard entries named in bb=, after the tick)
// An exception ends the trace with "exception" (its message on a following '#' line).
// Lines starting with '#' are information (every status transition), not compared.

#include <behaviortree_cpp/bt_factory.h>
#include <behaviortree_cpp/loggers/abstract_logger.h>

#include <charconv>
#include <filesystem>
#include <chrono>
#include <fstream>
#include <iostream>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace
{
std::vector<std::string>& events()
{
  static std::vector<std::string> list;
  return list;
}

std::mutex& events_mutex()
{
  static std::mutex m;
  return m;
}

void record(const std::string& line)
{
  const std::lock_guard<std::mutex> lock(events_mutex());
  events().push_back(line);
}

std::vector<std::string> split(const std::string& text, char sep)
{
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while(std::getline(ss, item, sep))
  {
    if(!item.empty())
    {
      out.push_back(item);
    }
  }
  return out;
}

class Scripted : public BT::ActionNodeBase
{
public:
  Scripted(const std::string& name, const BT::NodeConfig& config) : BT::ActionNodeBase(name, config)
  {}

  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<std::string>("results", "S", "per-tick results: S, F or R") };
  }

  BT::NodeStatus tick() override
  {
    if(!loaded_)
    {
      std::string text = "S";
      (void)getInput("results", text);
      results_ = split(text, ',');
      loaded_ = true;
    }
    const std::string& r = results_.empty() ? std::string("S") :
                           results_[std::min(index_, results_.size() - 1)];
    index_++;
    record(name() + " " + r);
    if(r == "R")
    {
      return BT::NodeStatus::RUNNING;
    }
    return r == "F" ? BT::NodeStatus::FAILURE : BT::NodeStatus::SUCCESS;
  }

  void halt() override
  {
    record(name() + " halt");
  }

private:
  bool loaded_ = false;
  std::vector<std::string> results_;
  size_t index_ = 0;
};

// A stub decorator for a model's Decorator: ticks its child and passes the status up.
class StubDecorator : public BT::DecoratorNode
{
public:
  StubDecorator(const std::string& name, const BT::NodeConfig& config)
    : BT::DecoratorNode(name, config)
  {}

private:
  BT::NodeStatus tick() override
  {
    setStatus(BT::NodeStatus::RUNNING);
    const BT::NodeStatus status = child_node_->executeTick();
    if(BT::isStatusCompleted(status))
    {
      resetChild();
    }
    return status;
  }
};

class TransitionLog : public BT::StatusChangeLogger
{
public:
  explicit TransitionLog(BT::TreeNode* root)
  {
    enableTransitionToIdle(true);
    subscribeToTreeChanges(root);
  }
  ~TransitionLog() override
  {
    unsubscribeFromTreeChanges();
  }
  void callback(BT::Duration, const BT::TreeNode& node, BT::NodeStatus prev,
                BT::NodeStatus status) override
  {
    record("#" + node.name() + " " + BT::toStr(prev) + "->" + BT::toStr(status));
  }
  void flush() override
  {}
};

std::string show(const BT::Any& value)
{
  if(value.empty())
  {
    return "<empty>";
  }
  if(value.type() == typeid(bool))
  {
    return value.cast<bool>() ? "true" : "false";
  }
  if(value.isIntegral())
  {
    return std::to_string(value.cast<int64_t>());
  }
  if(value.isNumber())
  {
    const double d = value.cast<double>();
    char buf[64];
    auto res = std::to_chars(buf, buf + sizeof(buf), d);
    return std::string(buf, res.ptr);
  }
  if(value.isString())
  {
    return "'" + value.cast<std::string>() + "'";
  }
  return "<" + BT::demangle(value.type()) + ">";
}

struct Config
{
  int ticks = 5;
  int period_ms = 0;
  std::vector<std::string> keys;
};

Config read_config(const std::string& text)
{
  Config config;
  std::smatch m;
  if(std::regex_search(text, m, std::regex("<!--\\s*conformance([^>]*)-->")))
  {
    const std::string body = m[1];
    std::smatch kv;
    if(std::regex_search(body, kv, std::regex("ticks=(\\d+)")))
    {
      config.ticks = std::stoi(kv[1]);
    }
    if(std::regex_search(body, kv, std::regex("period_ms=(\\d+)")))
    {
      config.period_ms = std::stoi(kv[1]);
    }
    if(std::regex_search(body, kv, std::regex("bb=([A-Za-z0-9_@,/]+)")))
    {
      config.keys = split(kv[1], ',');
    }
  }
  return config;
}

std::string read_file(const std::string& path)
{
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void flush_events(std::ostream& out)
{
  const std::lock_guard<std::mutex> lock(events_mutex());
  for(const auto& e : events())
  {
    out << (e[0] == '#' ? "" : "  ") << e << "\n";
  }
  events().clear();
}

// A manifest line: "Action GoTo waypoint >held_at" ('>' marks an output port).
void register_stubs(BT::BehaviorTreeFactory& factory, const std::string& manifest)
{
  std::stringstream ss(read_file(manifest));
  std::string line;
  const auto builtins = factory.builtinNodes();
  while(std::getline(ss, line))
  {
    auto words = split(line, ' ');
    if(words.size() < 2 || builtins.count(words[1]) != 0)
    {
      continue;
    }
    BT::PortsList ports;
    for(size_t i = 2; i < words.size(); i++)
    {
      if(words[i][0] == '>')
      {
        ports.insert(BT::OutputPort<BT::AnyTypeAllowed>(words[i].substr(1)));
      }
      else
      {
        ports.insert(BT::InputPort<BT::AnyTypeAllowed>(words[i]));
      }
    }
    const std::string id = words[1];
    auto stub = [id](BT::TreeNode& node) {
      record(node.name() + " " + id);
      return BT::NodeStatus::SUCCESS;
    };
    if(words[0] == "Decorator")
    {
      BT::TreeNodeManifest model{ BT::NodeType::DECORATOR, id, ports, {} };
      factory.registerBuilder(model, [](const std::string& name, const BT::NodeConfig& config) {
        return std::make_unique<StubDecorator>(name, config);
      });
    }
    else if(words[0] == "Condition")
    {
      factory.registerSimpleCondition(id, stub, ports);
    }
    else
    {
      factory.registerSimpleAction(id, stub, ports);
    }
  }
}

// What BT.CPP itself prints on std::cout (Blackboard::debugMessage() before a type error) is
// information: it is kept, after the trace line it belongs to, as '#' lines.
class CaptureStdout
{
public:
  CaptureStdout() : previous_(std::cout.rdbuf(captured_.rdbuf()))
  {}
  ~CaptureStdout()
  {
    restore();
  }
  std::string release()
  {
    restore();
    std::string out;
    std::string line;
    while(std::getline(captured_, line))
    {
      out += "# btcpp: " + line + "\n";
    }
    captured_.str("");
    captured_.clear();
    return out;
  }

private:
  void restore()
  {
    if(previous_ != nullptr)
    {
      std::cout.rdbuf(previous_);
      previous_ = nullptr;
    }
  }
  std::stringstream captured_;
  std::streambuf* previous_;
};

int run(BT::BehaviorTreeFactory& factory, const std::string& tree_path)
{
  const std::string text = read_file(tree_path);
  const Config config = read_config(text);
  BT::Tree tree;
  try
  {
    CaptureStdout capture;
    try
    {
      tree = factory.createTreeFromFile(std::filesystem::absolute(tree_path));
    }
    catch(...)
    {
      const std::string printed = capture.release();
      std::cout << "load error\n" << printed;
      throw;
    }
    std::cout << capture.release();
  }
  catch(const std::exception& e)
  {
    std::cout << "# " << std::regex_replace(e.what(), std::regex("\n"), " ") << "\n";
    return 0;
  }
  TransitionLog log(tree.rootNode());
  for(int n = 1; n <= config.ticks; n++)
  {
    if(n > 1 && config.period_ms > 0)
    {
      std::this_thread::sleep_for(std::chrono::milliseconds(config.period_ms));
    }
    BT::NodeStatus status;
    CaptureStdout capture;
    try
    {
      status = tree.tickExactlyOnce();
    }
    catch(const std::exception& e)
    {
      const std::string printed = capture.release();
      std::cout << "tick " << n << " exception\n";
      flush_events(std::cout);
      std::cout << printed << "# " << std::regex_replace(e.what(), std::regex("\n"), " ") << "\n";
      return 0;
    }
    const std::string printed = capture.release();
    std::cout << "tick " << n << " " << BT::toStr(status) << "\n";
    flush_events(std::cout);
    std::cout << printed;
    for(const auto& key : config.keys)
    {
      auto entry = tree.rootBlackboard()->getEntry(key);
      std::cout << "bb " << key << "=" << (entry ? show(entry->value) : "<none>") << "\n";
    }
  }
  return 0;
}
}  // namespace

int main(int argc, char** argv)
{
  const std::vector<std::string> args(argv + 1, argv + argc);
  BT::BehaviorTreeFactory factory;
  factory.registerNodeType<Scripted>("Scripted");
  // Enums for the scripting tests (script_enums).
  factory.registerScriptingEnum("RED", 1);
  factory.registerScriptingEnum("GREEN", 2);
  factory.registerScriptingEnum("BLUE", 3);
  if(args.size() == 2 && args[0] == "trace")
  {
    return run(factory, args[1]);
  }
  if(args.size() == 3 && args[0] == "stubs")
  {
    register_stubs(factory, args[1]);
    return run(factory, args[2]);
  }
  std::cerr << "usage: conformance_harness trace TREE.xml | stubs MANIFEST TREE.xml\n";
  return 2;
}
